//! Maximum-length pseudo-random binary sequences (PRBS): the input of the paper's experiment
//! (a 10-bit register, period 1023), from a Fibonacci linear-feedback shift register.

use crate::error::{Error, Result};

/// Feedback taps of maximum-length Fibonacci LFSRs: the exponents `e` of the primitive
/// polynomial `x^n + ... + 1` other than 0, for `n = 2..=32` (standard tables, e.g. Xilinx
/// XAPP052; every entry is checked to give period `2^n - 1` by the tests).
const TAPS: [&[u32]; 31] = [
    &[2, 1],
    &[3, 2],
    &[4, 3],
    &[5, 3],
    &[6, 5],
    &[7, 6],
    &[8, 6, 5, 4],
    &[9, 5],
    &[10, 7],
    &[11, 9],
    &[12, 6, 4, 1],
    &[13, 4, 3, 1],
    &[14, 5, 3, 1],
    &[15, 14],
    &[16, 15, 13, 4],
    &[17, 14],
    &[18, 11],
    &[19, 6, 2, 1],
    &[20, 17],
    &[21, 19],
    &[22, 21],
    &[23, 18],
    &[24, 23, 22, 17],
    &[25, 22],
    &[26, 6, 2, 1],
    &[27, 5, 2, 1],
    &[28, 25],
    &[29, 27],
    &[30, 6, 4, 1],
    &[31, 28],
    &[32, 22, 2, 1],
];

/// Supported shift-register lengths of [`prbs`].
pub const PRBS_BITS: std::ops::RangeInclusive<u32> = 2..=32;

/// Fibonacci LFSR: the output is the lowest bit, the feedback (parity of the tapped bits)
/// enters at the top.
pub(super) struct Lfsr {
    state: u64,
    mask: u64,
    top: u32,
}

impl Lfsr {
    pub(super) fn new(bits: u32, seed: u64) -> Result<Self> {
        if !PRBS_BITS.contains(&bits) {
            return Err(Error::Invalid(format!(
                "PRBS register length {bits} bits is not supported (use {} to {})",
                PRBS_BITS.start(),
                PRBS_BITS.end()
            )));
        }
        // Tap exponent e reads the bit that left the top e steps ago: bit (bits - e).
        let mask = TAPS[(bits - 2) as usize].iter().fold(0u64, |m, &e| m | 1 << (bits - e));
        let period = (1u64 << bits) - 1;
        // Any nonzero state is a phase of the same m-sequence; seeds below the period give
        // distinct phases, so nearby seeds never repeat each other's input.
        let state = 1 + seed % period;
        Ok(Lfsr { state, mask, top: bits - 1 })
    }

    pub(super) fn next_bit(&mut self) -> bool {
        let out = self.state & 1 == 1;
        let fb = u64::from((self.state & self.mask).count_ones() & 1);
        self.state = (self.state >> 1) | (fb << self.top);
        out
    }
}

/// Maximum-length pseudo-random binary sequence of `n` samples, levels `+amplitude` (register
/// output 1) and `-amplitude` (0), period `2^bits - 1` (one period holds one more `+` than `-`).
/// `seed` picks the initial register state `1 + seed mod (2^bits - 1)`, i.e. the phase.
/// Fails (`Error::Invalid`) for `bits` outside 2..=32.
pub fn prbs(bits: u32, amplitude: f64, seed: u64, n: usize) -> Result<Vec<f64>> {
    let mut reg = Lfsr::new(bits, seed)?;
    Ok((0..n).map(|_| if reg.next_bit() { amplitude } else { -amplitude }).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Smallest p > 0 with x[i + p] == x[i] for all i (x must hold at least two periods).
    fn min_period(x: &[f64], candidates: &[usize]) -> Option<usize> {
        candidates
            .iter()
            .copied()
            .filter(|&p| p > 0 && p < x.len())
            .find(|&p| (0..x.len() - p).all(|i| x[i] == x[i + p]))
    }

    fn divisors(n: usize) -> Vec<usize> {
        (1..=n).filter(|&d| n.is_multiple_of(d)).collect()
    }

    #[test]
    fn prbs_has_maximal_period_and_balanced_levels() {
        for bits in 3..=16u32 {
            let period = (1usize << bits) - 1;
            for seed in [0u64, 12345] {
                let x = prbs(bits, 2.5, seed, 2 * period + 5).unwrap();
                // Every period divides the minimal one, so testing the divisors suffices.
                assert_eq!(min_period(&x, &divisors(period)), Some(period), "bits {bits}");
                assert!(x.iter().all(|&v| v == 2.5 || v == -2.5));
                let plus = x[..period].iter().filter(|&&v| v > 0.0).count();
                assert_eq!(plus, period - plus + 1, "bits {bits}");
            }
        }
    }

    #[test]
    fn lfsr_state_returns_after_exactly_one_period() {
        for bits in 2..=20u32 {
            let mut r = Lfsr::new(bits, 0).unwrap();
            let start = r.state;
            let period = (1u64 << bits) - 1;
            for step in 1..=period {
                r.next_bit();
                if r.state == start {
                    assert_eq!(step, period, "bits {bits}");
                }
            }
            assert_eq!(r.state, start, "bits {bits}");
        }
    }

    /// All 31 tap sets, up to 32 bits (about 8.6e9 steps; run with `--ignored`).
    #[test]
    #[ignore]
    fn lfsr_all_tables_are_maximal() {
        for bits in 2..=32u32 {
            let mut r = Lfsr::new(bits, 0).unwrap();
            let start = r.state;
            let period = (1u64 << bits) - 1;
            let mut step = 0u64;
            loop {
                r.next_bit();
                step += 1;
                if r.state == start {
                    break;
                }
            }
            assert_eq!(step, period, "bits {bits}");
        }
    }

    #[test]
    fn prbs_rejects_unsupported_lengths() {
        for bits in [0, 1, 33, 64] {
            let e = prbs(bits, 1.0, 0, 10).unwrap_err();
            assert!(matches!(e, Error::Invalid(_)));
            assert!(e.to_string().contains("not supported"), "{e}");
        }
        assert_eq!(prbs(10, 1.0, 0, 0).unwrap().len(), 0);
    }

    #[test]
    fn prbs_seed_picks_the_phase() {
        let a = prbs(10, 1.0, 1, 1023).unwrap();
        let b = prbs(10, 1.0, 2, 1023).unwrap();
        assert_ne!(a, b);
        // Same m-sequence, other phase: b is a rotation of a.
        let shift = (0..1023).find(|&s| (0..1023).all(|i| a[(i + s) % 1023] == b[i]));
        assert!(shift.is_some());
        // Seeds are taken modulo the period.
        assert_eq!(prbs(10, 1.0, 1 + 1023, 50).unwrap(), a[..50]);
    }
}

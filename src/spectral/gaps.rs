//! The Welch segments of a record with missing outputs (METHOD.md 21.3).
//!
//! A Welch segment needs M consecutive outputs, so the segments are taken only inside the
//! stretches of observed outputs (`data::observed_ranges`: the experiments cut at every missing
//! sample), each stretch cut as a record is (segments of M starting every `S = round(M (1 -
//! overlap))` samples, its tail unused) and a stretch shorter than M left out. Nothing is
//! filled in: the estimate is Welch's on the samples it uses.
//!
//! The segment length trades resolution against the data used: the longer M, the fewer
//! stretches hold a segment. M is the largest power of two, at most the requested length and
//! half the observed samples (a complete record's cap), whose segments cover at least half as
//! many observed samples as segments of the shortest length ([`MIN_SEGMENT`], 16) would, with
//! at least two segments (one segment's coherence is identically 1). Short bursts of gaps in a
//! long record keep long segments; outputs missing at random every ~20 samples leave short
//! ones (METHOD.md 21.3 shows both). No two segments of 16: an error naming the longest stretch.

use super::{MIN_SEGMENT, WelchOptions};
use crate::error::{Error, Result};

/// The segment length and the segments' starts of a record of `n` samples with experiments
/// beginning at `seams` and the outputs at `missing` (sorted, not empty) missing.
pub(super) fn segments(
    n: usize,
    seams: &[usize],
    missing: &[usize],
    opts: &WelchOptions,
) -> Result<(usize, Vec<usize>)> {
    let stretches = crate::data::observed_ranges(n, seams, missing);
    let observed: usize = stretches.iter().map(|e| e.len()).sum();
    let longest = stretches.iter().map(|e| e.len()).max().unwrap_or(0);
    let starts_of = |m: usize| {
        let step = ((m as f64 * (1.0 - opts.overlap)).round() as usize).clamp(1, m);
        stretches
            .iter()
            .filter(|e| e.len() >= m)
            .flat_map(|e| (0..1 + (e.len() - m) / step).map(move |s| e.start + s * step))
            .collect::<Vec<usize>>()
    };
    let shortest = starts_of(MIN_SEGMENT);
    if shortest.len() < 2 {
        return Err(Error::Invalid(format!(
            "spectral estimate: the longest stretch without a missing output has {longest} samples \
             ({observed} of {n} outputs observed, {} missing); the estimate needs two segments of at least \
             {MIN_SEGMENT} consecutive observed samples, and {} fit",
            missing.len(),
            shortest.len()
        )));
    }
    let base = covered(&shortest, MIN_SEGMENT);
    let cap = opts.segment.min(observed / 2).max(MIN_SEGMENT);
    let mut m = 1usize << (usize::BITS - 1 - cap.leading_zeros());
    while m > MIN_SEGMENT {
        let starts = starts_of(m);
        if starts.len() >= 2 && 2 * covered(&starts, m) >= base {
            return Ok((m, starts));
        }
        m /= 2;
    }
    Ok((MIN_SEGMENT, shortest))
}

/// The samples inside at least one segment of length `m` starting at `starts` (ascending).
pub(super) fn covered(starts: &[usize], m: usize) -> usize {
    starts.windows(2).map(|w| (w[1] - w[0]).min(m)).sum::<usize>() + if starts.is_empty() { 0 } else { m }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every segment lies inside one stretch of observed outputs (no missing sample, no seam in
    /// it), and the length is the longest whose segments cover half the 16-sample cover.
    #[test]
    fn segments_stay_inside_the_stretches() {
        let n = 3000;
        let seams = [1500];
        // Bursts of 20 and a few isolated gaps.
        let mut missing: Vec<usize> = (400..420).chain(1000..1020).chain(2200..2220).collect();
        missing.extend([37, 1777, 2900]);
        missing.sort_unstable();
        let opts = WelchOptions::default();
        let (m, starts) = segments(n, &seams, &missing, &opts).expect("long stretches");
        assert!(m.is_power_of_two() && m >= MIN_SEGMENT);
        for &s in &starts {
            assert!(!missing.iter().any(|&t| (s..s + m).contains(&t)), "segment at {s} holds a gap");
            assert!(!seams.iter().any(|&t| s < t && t < s + m), "segment at {s} crosses a seam");
        }
        // The rule: twice the cover at m reaches the 16-sample cover, and at 2m it does not.
        let cover = |m: usize| {
            let step = m / 2;
            let st: Vec<usize> = crate::data::observed_ranges(n, &seams, &missing)
                .into_iter()
                .filter(|e| e.len() >= m)
                .flat_map(|e| (0..1 + (e.len() - m) / step).map(move |s| e.start + s * step))
                .collect();
            (st.len(), covered(&st, m))
        };
        assert!(2 * cover(m).1 >= cover(16).1);
        let (k2, c2) = cover(2 * m);
        assert!(k2 < 2 || 2 * c2 < cover(16).1 || 2 * m > opts.segment.min((n - missing.len()) / 2));
    }

    #[test]
    fn no_two_segments_is_an_error_naming_the_longest_stretch() {
        // Every 10th output missing: stretches of 9.
        let n = 400;
        let missing: Vec<usize> = (0..n).filter(|t| t % 10 == 9).collect();
        let e = segments(n, &[], &missing, &WelchOptions::default()).unwrap_err().to_string();
        assert!(e.contains("longest stretch without a missing output has 9 samples"), "{e}");
        assert!(e.contains("360 of 400 outputs observed, 40 missing"), "{e}");
    }

    #[test]
    fn the_cover_counts_overlaps_once() {
        assert_eq!(covered(&[0, 8, 16, 100], 16), 8 + 8 + 16 + 16);
        assert_eq!(covered(&[], 16), 0);
    }
}

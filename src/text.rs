//! How numbers read in messages, the summary and the report: one home for their formatting.

/// `v` with `digits` significant digits, in exponent form when very small or large.
pub fn sig(v: f64, digits: usize) -> String {
    if !v.is_finite() {
        return "n/a".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let mag = v.abs().log10().floor() as i32;
    if !(-3..6).contains(&mag) {
        return format!("{:.*e}", digits.saturating_sub(1), v);
    }
    let decimals = (digits as i32 - 1 - mag).max(0) as usize;
    let s = format!("{v:.decimals$}");
    // "-0.000" would read as a sign error on an axis.
    if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') { "0".into() } else { s }
}

/// `digits` significant digits without trailing zeros ("0.6034", "0.05", "2.5e-5").
pub fn trimmed(v: f64, digits: usize) -> String {
    let s = sig(v, digits);
    match s.split_once('e') {
        Some((m, e)) if m.contains('.') => format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.')),
        None if s.contains('.') => s.trim_end_matches('0').trim_end_matches('.').to_string(),
        _ => s,
    }
}

/// A tuning constant k as every message prints it: four significant digits ("0.6034", "0.05",
/// "2"). The table and selection.json keep k exactly (and its `k_index`).
pub fn k(k: f64) -> String {
    trimmed(k, 4)
}

/// A count with its noun, singular for one ("1 round", "3 rounds"); `noun` is the singular and
/// takes an "s" in the plural.
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 { format!("1 {noun}") } else { format!("{n} {noun}s") }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_count_of_one_is_singular() {
        assert_eq!(super::count(1, "round"), "1 round");
        assert_eq!(super::count(0, "array"), "0 arrays");
        assert_eq!(super::count(10, "round"), "10 rounds");
    }

    #[test]
    fn k_reads_with_four_significant_digits() {
        assert_eq!(super::k(0.6034176336545164), "0.6034");
        assert_eq!(super::k(0.05), "0.05");
        assert_eq!(super::k(2.0), "2");
        assert_eq!(super::k(0.21867241478865565), "0.2187");
    }
}

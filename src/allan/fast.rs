//! Whole-record estimators on phase data: O(N) per averaging factor, returning (variance, terms).
//!
//! These are the batch paths behind [`super::estimate`]. OADEV, ADEV and HDEV read the phase array
//! directly (each term is a fresh second or third difference, so nothing accumulates); MDEV needs
//! sums of m consecutive second differences and takes them from a prefix sum of those differences,
//! which is O(N) instead of the definition's O(N·m). The prefix sum stays small because the second
//! differences have zero mean, so its rounding error is negligible against the 1e-4 reference
//! tolerance (checked against [`super::naive`] on random input for every τ).
//!
//! # References
//! Riley W. J., NIST SP 1065, 2008, §5.2 (definitions; see [`super::naive`] for the formulas).

/// Overlapping Allan variance and its number of terms, `None` when L < 2m + 1.
pub fn oavar(x: &[f64], tau0: f64, m: usize) -> Option<(f64, usize)> {
    second_differences(x, tau0, m, 1)
}

/// Non-overlapping Allan variance and its number of terms, `None` when L < 2m + 1.
pub fn avar(x: &[f64], tau0: f64, m: usize) -> Option<(f64, usize)> {
    second_differences(x, tau0, m, m)
}

/// Allan variance from second differences taken every `stride` phase points.
fn second_differences(x: &[f64], tau0: f64, m: usize, stride: usize) -> Option<(f64, usize)> {
    if m == 0 || x.len() < 2 * m + 1 {
        return None;
    }
    let (sum, terms) = x[..x.len() - 2 * m]
        .iter()
        .zip(&x[m..])
        .zip(&x[2 * m..])
        .step_by(stride)
        .fold((0.0, 0usize), |(s, n), ((&a, &b), &c)| {
            let d = c - 2.0 * b + a;
            (s + d * d, n + 1)
        });
    let tau = m as f64 * tau0;
    Some((sum / (2.0 * tau * tau * terms as f64), terms))
}

/// Non-overlapping Hadamard variance and its number of terms, `None` when L < 3m + 1.
pub fn hvar(x: &[f64], tau0: f64, m: usize) -> Option<(f64, usize)> {
    if m == 0 || x.len() < 3 * m + 1 {
        return None;
    }
    let (sum, terms) = (0..x.len() - 3 * m)
        .step_by(m)
        .fold((0.0, 0usize), |(s, n), i| {
            let d = x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i];
            (s + d * d, n + 1)
        });
    let tau = m as f64 * tau0;
    Some((sum / (6.0 * tau * tau * terms as f64), terms))
}

/// Modified Allan variance and its number of terms, `None` when L < 3m + 1.
///
/// # Formula
/// ```text
/// D[k] = Σ_{i<k} (x[i+2m] − 2·x[i+m] + x[i]),   Mod σ² = Σ_j (D[j+m] − D[j])² / (2·m²·τ²·(L − 3m + 1))
/// ```
pub fn mvar(x: &[f64], tau0: f64, m: usize) -> Option<(f64, usize)> {
    let l = x.len();
    if m == 0 || l < 3 * m + 1 {
        return None;
    }
    let n_diff = l - 2 * m;
    let mut prefix = Vec::with_capacity(n_diff + 1);
    let mut acc = 0.0;
    prefix.push(acc);
    for i in 0..n_diff {
        acc += x[i + 2 * m] - 2.0 * x[i + m] + x[i];
        prefix.push(acc);
    }
    let terms = l - 3 * m + 1;
    let sum: f64 = prefix[m..]
        .iter()
        .zip(&prefix)
        .take(terms)
        .map(|(hi, lo)| (hi - lo).powi(2))
        .sum();
    let tau = m as f64 * tau0;
    let mf = m as f64;
    Some((sum / (2.0 * mf * mf * tau * tau * terms as f64), terms))
}

#[cfg(test)]
mod tests {
    use super::super::naive;
    use super::*;
    use proptest::prelude::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * b.abs().max(f64::MIN_POSITIVE)
    }

    proptest! {
        // Every fast path equals the literal definition, at every averaging factor.
        #[test]
        fn fast_paths_match_naive(x in prop::collection::vec(-1e3f64..1e3, 4..200), tau0 in 0.001f64..10.0) {
            for m in 1..=x.len() {
                let pairs: [(Option<(f64, usize)>, Option<f64>); 4] = [
                    (oavar(&x, tau0, m), naive::oavar(&x, tau0, m)),
                    (avar(&x, tau0, m), naive::avar(&x, tau0, m)),
                    (hvar(&x, tau0, m), naive::hvar(&x, tau0, m)),
                    (mvar(&x, tau0, m), naive::mvar(&x, tau0, m)),
                ];
                for (fast, slow) in pairs {
                    match (fast, slow) {
                        (Some((f, _)), Some(s)) => prop_assert!(close(f, s), "m={m}: {f} vs {s}"),
                        (None, None) => {}
                        other => prop_assert!(false, "m={m}: {other:?}"),
                    }
                }
            }
        }

        // Properties: non-negative, scale c² , offset and linear phase (frequency offset) change nothing.
        #[test]
        fn scaling_and_offset(x in prop::collection::vec(-1e3f64..1e3, 7..100), c in 0.1f64..10.0, off in -1e3f64..1e3) {
            let scaled: Vec<f64> = x.iter().map(|v| c * v + off).collect();
            for m in 1..=x.len() / 3 {
                let (a, _) = oavar(&x, 1.0, m).unwrap();
                let (b, _) = oavar(&scaled, 1.0, m).unwrap();
                prop_assert!(a >= 0.0);
                prop_assert!((b - c * c * a).abs() <= 1e-7 * (c * c * a).max(1e-9), "{b} vs {}", c * c * a);
            }
        }
    }

    #[test]
    fn term_counts_are_stable32s() {
        let x = vec![0.0; 1001];
        assert_eq!(oavar(&x, 1.0, 2).unwrap().1, 997);
        assert_eq!(avar(&x, 1.0, 2).unwrap().1, 499);
        assert_eq!(mvar(&x, 1.0, 2).unwrap().1, 996);
        assert_eq!(hvar(&x, 1.0, 2).unwrap().1, 498);
    }
}

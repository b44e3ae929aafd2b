//! Textbook brute-force definitions: the oracle that fast and streaming paths must match.
//!
//! These loop over every term exactly as NIST SP 1065 writes them, with no running sums, so that a
//! disagreement always means the fast path is wrong. They are O(N) per τ and only used by tests,
//! benchmarks and as a reference.
//!
//! # References
//! Riley W. J., "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008, §5.2.2 (AVAR),
//! §5.2.4 (OAVAR), §5.2.5 (MVAR), §5.2.8 (HVAR).

/// Phase from rate: `x[0] = 0`, `x[n+1] = x[n] + τ0·y[n]` (N rate samples give N+1 phase points).
///
/// ```
/// let x = fdavar::allan::naive::phase_from_rate(&[1.0, 2.0, 3.0], 0.5);
/// assert_eq!(x, vec![0.0, 0.5, 1.5, 3.0]);
/// ```
pub fn phase_from_rate(rate: &[f64], tau0: f64) -> Vec<f64> {
    let mut x = Vec::with_capacity(rate.len() + 1);
    let mut acc = 0.0;
    x.push(acc);
    for &y in rate {
        acc += tau0 * y;
        x.push(acc);
    }
    x
}

/// Overlapping Allan variance of phase data at averaging factor `m`.
///
/// # Formula
/// ```text
/// σ²(τ) = Σ_{i=0}^{L−2m−1} (x[i+2m] − 2·x[i+m] + x[i])² / (2·τ²·(L − 2m)),   τ = m·τ0
/// ```
/// where L is the number of phase points. Returns `None` when L < 2m + 1.
///
/// ```
/// // NBS-14 (NIST SP 1065 p. 107): OADEV(τ=2) = 85.95287.
/// let x = [0.0, 103.11111, 123.22222, 157.33333, 166.44444, 48.55555, -96.33333, -2.22222, 111.88889, 0.0];
/// let s = fdavar::allan::naive::oavar(&x, 1.0, 2).unwrap().sqrt();
/// assert!((s - 85.95287).abs() < 1e-4);
/// ```
pub fn oavar(x: &[f64], tau0: f64, m: usize) -> Option<f64> {
    let l = x.len();
    if m == 0 || l < 2 * m + 1 {
        return None;
    }
    let terms = l - 2 * m;
    let sum: f64 = (0..terms)
        .map(|i| {
            let d = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
            d * d
        })
        .sum();
    let tau = m as f64 * tau0;
    Some(sum / (2.0 * tau * tau * terms as f64))
}

/// Non-overlapping Allan variance of phase data at averaging factor `m` (stride m).
///
/// # Formula
/// ```text
/// σ²(τ) = Σ_{j=0}^{J−1} (x[(j+2)m] − 2·x[(j+1)m] + x[jm])² / (2·τ²·J),   J = ⌊(L−1)/m⌋ − 1
/// ```
pub fn avar(x: &[f64], tau0: f64, m: usize) -> Option<f64> {
    let l = x.len();
    if m == 0 || l < 2 * m + 1 {
        return None;
    }
    let j = (l - 1) / m - 1;
    let sum: f64 = (0..j)
        .map(|k| {
            let i = k * m;
            let d = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
            d * d
        })
        .sum();
    let tau = m as f64 * tau0;
    Some(sum / (2.0 * tau * tau * j as f64))
}

/// Modified Allan variance of phase data at averaging factor `m`.
///
/// # Formula
/// ```text
/// Mod σ²(τ) = Σ_{j=0}^{L−3m} ( Σ_{i=j}^{j+m−1} (x[i+2m] − 2·x[i+m] + x[i]) )² / (2·m²·τ²·(L − 3m + 1))
/// ```
pub fn mvar(x: &[f64], tau0: f64, m: usize) -> Option<f64> {
    let l = x.len();
    if m == 0 || l < 3 * m + 1 {
        return None;
    }
    let outer = l - 3 * m + 1;
    let sum: f64 = (0..outer)
        .map(|j| {
            let inner: f64 = (j..j + m)
                .map(|i| x[i + 2 * m] - 2.0 * x[i + m] + x[i])
                .sum();
            inner * inner
        })
        .sum();
    let tau = m as f64 * tau0;
    let mf = m as f64;
    Some(sum / (2.0 * mf * mf * tau * tau * outer as f64))
}

/// Non-overlapping Hadamard variance of phase data at averaging factor `m` (stride m).
///
/// # Formula
/// ```text
/// Hσ²(τ) = Σ_{j=0}^{J−1} (x[(j+3)m] − 3·x[(j+2)m] + 3·x[(j+1)m] − x[jm])² / (6·τ²·J),   J = ⌊(L−1)/m⌋ − 2
/// ```
pub fn hvar(x: &[f64], tau0: f64, m: usize) -> Option<f64> {
    let l = x.len();
    if m == 0 || l < 3 * m + 1 {
        return None;
    }
    let j = (l - 1) / m - 2;
    let sum: f64 = (0..j)
        .map(|k| {
            let i = k * m;
            let d = x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i];
            d * d
        })
        .sum();
    let tau = m as f64 * tau0;
    Some(sum / (6.0 * tau * tau * j as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    const NBS14_PHASE: [f64; 10] = [
        0.0, 103.11111, 123.22222, 157.33333, 166.44444, 48.55555, -96.33333, -2.22222, 111.88889,
        0.0,
    ];

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs()
    }

    #[test]
    fn nbs14_as_published() {
        let x = NBS14_PHASE;
        let dev = |f: fn(&[f64], f64, usize) -> Option<f64>, m| f(&x, 1.0, m).unwrap().sqrt();
        assert!(rel(dev(avar, 1), 91.22945) < 1e-6);
        assert!(rel(dev(avar, 2), 115.8082) < 1e-6);
        assert!(rel(dev(oavar, 1), 91.22945) < 1e-6);
        assert!(rel(dev(oavar, 2), 85.95287) < 1e-6);
        assert!(rel(dev(mvar, 1), 91.22945) < 1e-6);
        assert!(rel(dev(mvar, 2), 74.78849) < 1e-6);
        assert!(rel(dev(hvar, 1), 70.80608) < 1e-6);
        assert!(rel(dev(hvar, 2), 116.7980) < 1e-6);
    }
}

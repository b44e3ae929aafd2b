//! The measured side of the fit: whole-record overlapping Allan variance of a rate series, and
//! the EDF of an overlapping estimate for each power-law noise class.
//!
//! The fit needs the EDF *of the noise that is actually there*: an estimate at long τ dominated by
//! rate random walk has far fewer degrees of freedom than a white-noise formula claims, and a fit
//! weighted with the wrong EDF reports a failure where there is none. So the EDF is recomputed
//! from the fitted model's noise mix ([`edf_for_mix`]), iterating with the weights (DESIGN §5).
//! The simple closed forms of NIST SP 1065 Table 12 are used (documented there as within a few
//! per cent of Greenhall's algorithm for the overlapping estimator).
//!
//! # References
//! Riley W. J., "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008, §5.2.4 and
//! Table 12 (EDF approximations for overlapping ADEV).

use crate::allan::AllanPoint;
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// The power-law noise classes of NIST SP 1065, by the log-log slope of σ²(τ).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseClass {
    /// White phase (angle) noise, e.g. quantization: σ² ∝ τ⁻².
    WhitePm,
    /// White rate noise (angle random walk): σ² ∝ τ⁻¹.
    WhiteFm,
    /// Flicker rate noise (bias instability): σ² flat.
    FlickerFm,
    /// Rate random walk and slower (ramps): σ² ∝ τ or steeper.
    RandomWalkFm,
}

impl NoiseClass {
    /// The class whose AVAR slope is nearest `slope`; effects without a slope (sinusoid,
    /// Gauss–Markov) count as white rate noise, the class whose EDF formula is most generous
    /// and so never overstates a failure.
    pub fn from_slope(slope: Option<f64>) -> Self {
        match slope {
            Some(s) if s <= -1.5 => NoiseClass::WhitePm,
            Some(s) if s <= -0.5 => NoiseClass::WhiteFm,
            Some(s) if s < 0.5 => NoiseClass::FlickerFm,
            Some(_) => NoiseClass::RandomWalkFm,
            None => NoiseClass::WhiteFm,
        }
    }
}

/// EDF of an overlapping Allan variance estimate at averaging factor `m` from `n` phase points.
///
/// Returns at least 1 (an estimate is always worth one degree of freedom).
///
/// # Formula
/// ```text
/// white PM   : edf = (n+1)(n−2m) / (2(n−m))
/// white FM   : edf = [3(n−1)/(2m) − 2(n−2)/n] · 4m² / (4m² + 5)
/// flicker FM : edf = 2(n−2)/(2.3n − 4.9)            (m = 1)
///              edf = 5n² / (4m(n + 3m))              (m ≥ 2)
/// RW FM      : edf = (n−2)/m · ((n−1)² − 3m(n−1) + 4m²) / (n−3)²
/// ```
/// where n = number of phase points, m = averaging factor.
///
/// # References
/// NIST SP 1065 (Riley 2008), Table 12.
///
/// ```
/// use fdavar::model::measure::{edf_oavar, NoiseClass};
/// let e = edf_oavar(NoiseClass::WhiteFm, 1001, 1);
/// assert!((e - 665.0).abs() < 1.0);
/// ```
pub fn edf_oavar(class: NoiseClass, n: usize, m: usize) -> f64 {
    let (nf, mf) = (n as f64, m.max(1) as f64);
    let edf = match class {
        NoiseClass::WhitePm => (nf + 1.0) * (nf - 2.0 * mf) / (2.0 * (nf - mf)),
        NoiseClass::WhiteFm => {
            (3.0 * (nf - 1.0) / (2.0 * mf) - 2.0 * (nf - 2.0) / nf) * 4.0 * mf * mf
                / (4.0 * mf * mf + 5.0)
        }
        NoiseClass::FlickerFm if m <= 1 => 2.0 * (nf - 2.0) / (2.3 * nf - 4.9),
        NoiseClass::FlickerFm => 5.0 * nf * nf / (4.0 * mf * (nf + 3.0 * mf)),
        NoiseClass::RandomWalkFm => {
            (nf - 2.0) / mf * ((nf - 1.0).powi(2) - 3.0 * mf * (nf - 1.0) + 4.0 * mf * mf)
                / (nf - 3.0).powi(2)
        }
    };
    if edf.is_finite() {
        edf.max(1.0)
    } else {
        1.0
    }
}

/// EDF of an estimate whose expected value is the sum of independent parts `(variance, class)`.
///
/// # Formula
/// ```text
/// edf = (Σ vᵢ)² / Σ (vᵢ² / edfᵢ)
/// ```
/// (the variance of a sum of independent scaled χ² variables, matched to one scaled χ²).
pub fn edf_for_mix(parts: &[(f64, NoiseClass)], n: usize, m: usize) -> f64 {
    let total: f64 = parts.iter().map(|p| p.0).sum();
    let var: f64 = parts
        .iter()
        .map(|&(v, c)| v * v / edf_oavar(c, n, m))
        .sum();
    if total > 0.0 && var > 0.0 {
        (total * total / var).max(1.0)
    } else {
        edf_oavar(NoiseClass::WhiteFm, n, m)
    }
}

/// The 68.3 % χ² interval of a variance estimate with `edf` degrees of freedom.
pub fn chi2_interval(avar: f64, edf: f64) -> (f64, f64) {
    match ChiSquared::new(edf.max(1e-3)) {
        Ok(chi) => {
            let lo = chi.inverse_cdf(0.5 + 0.6827 / 2.0);
            let hi = chi.inverse_cdf(0.5 - 0.6827 / 2.0);
            (avar * edf / lo, avar * edf / hi)
        }
        Err(_) => (0.0, f64::INFINITY),
    }
}

/// Whole-record overlapping Allan variance of rate samples at the given averaging factors.
///
/// Terms that would straddle a NaN/Inf sample are left out (DESIGN §1), so the number of terms
/// can be smaller than L − 2m; a factor with no valid term is skipped. The EDF is the white-rate
/// value (the fit recomputes it from its model).
///
/// # Formula
/// ```text
/// x[0] = 0,  x[i+1] = x[i] + τ0·y[i]
/// σ²(τ) = Σ (x[i+2m] − 2x[i+m] + x[i])² / (2τ²·terms),   τ = m·τ0
/// ```
///
/// ```
/// let y: Vec<f64> = (0..1000).map(|i| if i % 2 == 0 { 1.0 } else { -1.0 }).collect();
/// let p = fdavar::model::measure::oavar_rate(&y, 0.1, &[1, 2]);
/// assert!((p[0].avar - 2.0).abs() < 1e-12 && p[1].avar.abs() < 1e-12);
/// ```
pub fn oavar_rate(rate: &[f64], tau0: f64, factors: &[usize]) -> Vec<AllanPoint> {
    let n = rate.len();
    let mut x = Vec::with_capacity(n + 1);
    let mut bad = Vec::with_capacity(n + 1);
    let (mut acc, mut nbad) = (0.0, 0usize);
    x.push(acc);
    bad.push(nbad);
    for &y in rate {
        if y.is_finite() {
            acc += tau0 * y;
        } else {
            nbad += 1;
        }
        x.push(acc);
        bad.push(nbad);
    }
    let clean = nbad == 0;
    factors
        .iter()
        .filter(|&&m| m >= 1 && n + 1 > 2 * m)
        .filter_map(|&m| {
            let (mut sum, mut terms) = (0.0, 0usize);
            for i in 0..n + 1 - 2 * m {
                if clean || bad[i + 2 * m] == bad[i] {
                    let d = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
                    sum += d * d;
                    terms += 1;
                }
            }
            if terms == 0 {
                return None;
            }
            let tau = m as f64 * tau0;
            let avar = sum / (2.0 * tau * tau * terms as f64);
            let edf = edf_oavar(NoiseClass::WhiteFm, terms + 2 * m, m);
            let (ci_low, ci_high) = chi2_interval(avar, edf);
            Some(AllanPoint { m, tau, avar, terms, edf, ci_low, ci_high })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allan::naive;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn matches_the_naive_oracle() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let y: Vec<f64> = (0..3000).map(|_| rng.random_range(-1.0..1.0)).collect();
        let x = naive::phase_from_rate(&y, 0.01);
        for p in oavar_rate(&y, 0.01, &[1, 2, 5, 17, 100, 999]) {
            let want = naive::oavar(&x, 0.01, p.m).unwrap();
            assert!((p.avar - want).abs() <= 1e-10 * want, "m={}", p.m);
            assert!(p.ci_low < p.avar && p.avar < p.ci_high);
        }
    }

    #[test]
    fn nan_terms_are_left_out() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut y: Vec<f64> = (0..2000).map(|_| rng.random_range(-1.0..1.0)).collect();
        y[1000] = f64::NAN;
        let p = oavar_rate(&y, 1.0, &[1, 10]);
        assert_eq!(p[0].terms, 2000 - 2 + 1 - 2);
        assert_eq!(p[1].terms, 2001 - 20 - 20);
        assert!(p.iter().all(|p| p.avar.is_finite()));
    }

    #[test]
    fn edf_formulas_behave() {
        for class in [
            NoiseClass::WhitePm,
            NoiseClass::WhiteFm,
            NoiseClass::FlickerFm,
            NoiseClass::RandomWalkFm,
        ] {
            let e: Vec<f64> = [1, 10, 100, 1000].iter().map(|&m| edf_oavar(class, 10_001, m)).collect();
            assert!(e.windows(2).all(|w| w[1] <= w[0]), "{class:?}: {e:?}");
        }
        // A mix of one part is that part.
        let one = edf_for_mix(&[(2.0, NoiseClass::FlickerFm)], 5000, 30);
        assert!((one - edf_oavar(NoiseClass::FlickerFm, 5000, 30)).abs() < 1e-9);
    }
}

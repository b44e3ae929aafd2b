//! The EDF of an overlapping Allan variance estimate for each power-law noise class, and of a mix.
//!
//! The fit needs the EDF *of the noise that is actually there*: an estimate at long τ dominated by
//! rate random walk has far fewer degrees of freedom than a white-noise formula claims, and a fit
//! weighted with the wrong EDF reports a failure where there is none. So the EDF is recomputed
//! from the fitted model's noise mix ([`edf_for_mix`]), iterating with the weights (docs/design.md §5).
//! The simple closed forms of NIST SP 1065 Table 12 are used (documented there as within a few
//! per cent of Greenhall's algorithm for the overlapping estimator).
//!
//! # References
//! Riley W. J., "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008, §5.2.4 and
//! Table 12 (EDF approximations for overlapping ADEV).

use crate::allan::edf::{chi2_interval_with, Chi2Inversion};

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
    /// The correlation length ℓ, in ln τ, of overlapping Allan estimates of this noise:
    /// ρ(τ₁, τ₂) ≈ exp(−(ln(τ₂/τ₁)/ℓ)²).
    ///
    /// Measured with `oavar_rate` (2¹⁶ samples, 200 seeded records, m from 100 and from 1000):
    /// white rate noise ρ = 0.91, 0.73, 0.51, 0.33, 0.11 at τ ratios 1.26, 1.58, 2, 2.5, 4
    /// (ℓ = 0.84 fits all five within 0.05); flicker (fdavar::sim) 0.96, 0.86, 0.75, 0.64, 0.45
    /// (ℓ = 1.29); rate random walk 0.985, 0.945, 0.884, 0.81, 0.67 (ℓ = 1.97). Near-neighbour
    /// correlation is that of a smooth curve (1 − d²/ℓ²), which an exponential kernel understates.
    /// White phase noise is taken as white rate noise (both dominated by the shortest differences).
    pub fn correlation_length(self) -> f64 {
        match self {
            NoiseClass::WhitePm | NoiseClass::WhiteFm => 0.84,
            NoiseClass::FlickerFm => 1.29,
            NoiseClass::RandomWalkFm => 1.97,
        }
    }

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
/// flicker FM : edf = 2(n−2)²/(2.3n − 4.9)           (m = 1)
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
        NoiseClass::FlickerFm if m <= 1 => 2.0 * (nf - 2.0).powi(2) / (2.3 * nf - 4.9),
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
    edf_of_mix(total, parts.iter().map(|&(v, c)| (v, edf_oavar(c, n, m))), || edf_oavar(NoiseClass::WhiteFm, n, m))
}

/// [`edf_for_mix`] from the parts' total, each part's variance beside its class's EDF, and the
/// white-FM EDF it falls back to: the same number, for callers that make the classes' EDFs once
/// and mix them many times (the fit's every round at every point).
pub fn edf_of_mix(total: f64, parts: impl Iterator<Item = (f64, f64)>, white_fm: impl FnOnce() -> f64) -> f64 {
    let var: f64 = parts.map(|(v, edf)| v * v / edf).sum();
    if total > 0.0 && var > 0.0 {
        (total * total / var).max(1.0)
    } else {
        white_fm()
    }
}

/// Two-sided level of a fit point's interval ([`crate::model::fit::FitPoint::ci`]): 68.27 %.
///
/// Written to four digits, not [`crate::allan::edf::ONE_SIGMA`]: the fit's CSV and figures have
/// always been computed with it, and the two differ in the last bits of every bound.
pub const FIT_CONFIDENCE: f64 = 0.6827;

/// The 68.3 % χ² interval of a variance estimate with `edf` degrees of freedom, as the fit reports
/// it ([`crate::model::fit::FitPoint::ci`]).
///
/// [`chi2_interval_with`] at [`FIT_CONFIDENCE`] with the polished quantiles
/// ([`Chi2Inversion::Newton`]), `edf` read as at least 10⁻³; `(0, ∞)` when no interval exists.
///
/// Why not statrs' own inversion, which the fit used until 2026-11-25: at EDF in the millions,
/// which the shortest τ of a long full-rate record reaches, it breaks down (measured: the lower
/// quantile NaN at 2·10⁶, the upper −∞ at 10⁷, both NaN at 10⁸), so the CSV's `adev_low` was NaN
/// and the figures drew the band down to 0 there. Below that the two agree to about 10⁻⁸.
///
/// # Formula
/// ```text
/// (low, high) = (edf·avar / χ²(1 − p ; edf), edf·avar / χ²(p ; edf)),   p = (1 − FIT_CONFIDENCE)/2
/// ```
/// where χ²(q ; ν) is the q-quantile of the χ² distribution with ν degrees of freedom.
///
/// ```
/// use fdavar::model::measure::chi2_interval;
/// let (lo, hi) = chi2_interval(1.0, 10.0);
/// // At the 68.2689 % level χ²(0.8413; 10) = 14.32551, χ²(0.1587; 10) = 5.68062
/// // (scipy.stats.chi2.ppf); 68.27 % moves them by less than 10⁻⁴.
/// assert!((lo - 10.0 / 14.32551).abs() < 1e-4 && (hi - 10.0 / 5.68062).abs() < 1e-4);
/// ```
pub fn chi2_interval(avar: f64, edf: f64) -> (f64, f64) {
    chi2_interval_with(avar, edf.max(1e-3), FIT_CONFIDENCE, Chi2Inversion::Newton)
        .unwrap_or((0.0, f64::INFINITY))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mix_is_the_squared_total_over_the_parts_variances() {
        use NoiseClass::*;
        let (n, m) = (10_001, 7);
        let (e1, e2) = (edf_oavar(WhiteFm, n, m), edf_oavar(RandomWalkFm, n, m));
        // (1 + 3)² / (1²/e1 + 3²/e2): the variance of a sum of independent scaled χ².
        let want = 16.0 / (1.0 / e1 + 9.0 / e2);
        let got = edf_for_mix(&[(1.0, WhiteFm), (3.0, RandomWalkFm)], n, m);
        assert!((got / want - 1.0).abs() < 1e-15, "{got} vs {want}");
        // From EDFs kept by the caller: the same bits.
        let kept = edf_of_mix(4.0, [(1.0, e1), (3.0, e2)].into_iter(), || unreachable!());
        assert_eq!(kept.to_bits(), got.to_bits());
        // No variance: white FM's EDF, asked only then.
        assert_eq!(edf_for_mix(&[(0.0, RandomWalkFm)], n, m), e1);
        assert_eq!(edf_of_mix(0.0, std::iter::empty(), || 42.0), 42.0);
    }

    #[test]
    fn chi2_interval_is_finite_and_tight_at_every_edf() {
        // scipy.stats.chi2.ppf(0.5 ± 0.6827/2, 10) = 14.325, 5.6806 (4 digits are enough to pin
        // the level); at large EDF the interval is avar·(1 ∓ √(2/edf)) to first order.
        let (lo, hi) = chi2_interval(1.0, 10.0);
        assert!((lo - 10.0 / 14.325).abs() < 1e-4 && (hi - 10.0 / 5.6806).abs() < 1e-4, "{lo} {hi}");
        for edf in [1.0, 3.5, 20.0, 800.0, 5e4, 3e5, 2e6, 1e7, 1e8] {
            let (lo, hi) = chi2_interval(2.5, edf);
            assert!(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo < 2.5 && 2.5 < hi, "edf {edf}: {lo} {hi}");
            if edf >= 800.0 {
                let half = 2.5 * (2.0 / edf).sqrt();
                assert!((2.5 - lo - half).abs() < 0.1 * half && (hi - 2.5 - half).abs() < 0.1 * half, "edf {edf}: {lo} {hi}");
            }
        }
        // Why the level survives the move to `allan::edf`: (1 − c)/2 and 1 − (1 − c)/2 are
        // exactly 0.5 ∓ c/2.
        let p = (1.0 - FIT_CONFIDENCE) / 2.0;
        assert_eq!(p, 0.5 - FIT_CONFIDENCE / 2.0);
        assert_eq!(1.0 - p, 0.5 + FIT_CONFIDENCE / 2.0);
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
        // NIST SP 1065 Table 12 at n = 1001 phase points, m = 10 (and m = 1 for flicker FM's own
        // formula), worked out by hand from the table: White PM 1002·981/(2·991), White FM
        // (150 − 2·999/1001)·400/405, Flicker FM 5·1001²/(40·1031), RW FM
        // 99.9·(1000² − 30·1000 + 400)/998², Flicker FM at m = 1 2·999²/(2.3·1001 − 4.9).
        for (class, m, want) in [
            (NoiseClass::WhitePm, 10, 495.944_5),
            (NoiseClass::WhiteFm, 10, 146.176_8),
            (NoiseClass::FlickerFm, 10, 121.484_1),
            (NoiseClass::RandomWalkFm, 10, 97.331_9),
            (NoiseClass::FlickerFm, 1, 868.809_1),
        ] {
            let e = edf_oavar(class, 1001, m);
            assert!((e - want).abs() < 1e-3, "{class:?} m = {m}: {e}, table {want}");
        }
        // A mix of one part is that part.
        let one = edf_for_mix(&[(2.0, NoiseClass::FlickerFm)], 5000, 30);
        assert!((one - edf_oavar(NoiseClass::FlickerFm, 5000, 30)).abs() < 1e-9);
        // Equal parts of white and random-walk FM: 2²/(1/146.1768 + 1/97.3319).
        let two = edf_for_mix(&[(1.0, NoiseClass::WhiteFm), (1.0, NoiseClass::RandomWalkFm)], 1001, 10);
        assert!((two - 233.711).abs() < 1e-2, "{two}");
    }
}

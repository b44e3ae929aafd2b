//! Time-domain estimators: effects located in time or driven by another signal.
//!
//! A bias step or a noise burst has no τ-law (its Allan signature depends on where it sits in the
//! record), and temperature or g-sensitivity is best measured against the signal that drives it.
//! So these effects are estimated on the rate samples, and removed from them before the Allan fit
//! of the rest. Each effect's estimator lives in its effect's file behind
//! [`TimeEstimator`](crate::model::effects::TimeEstimator), reached through
//! [`EffectKind::time_estimator`], so this module never names an effect; it holds the numerical
//! tools they share (the GLS regressions, the step and burst searches) and the tests the
//! diagnosis runs. Every value goes through the effect's `build`, which validates it.
//!
//! Estimation order: the regressions first, then the step, then the burst
//! ([`estimation_rank`](crate::model::effects::TimeEstimator::estimation_rank) says why).

use crate::model::effects::{EffectKind, Evidence, UNRANKED};
use crate::model::fit::{line_reach, AxisInput, FitError};
use crate::model::measure::NoiseClass;
use nalgebra::{DMatrix, DVector};
use realfft::{num_complex::Complex, RealFftPlanner, RealToComplex};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use statrs::function::erf::erfc;

/// What an estimator found: values in the effect's schema order, 1σ where known.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Parameter values in schema order, SI.
    pub values: Vec<f64>,
    /// 1σ uncertainties in schema order.
    pub sigmas: Vec<Option<f64>>,
    /// True when the effect is located in time (reported as an event).
    pub is_event: bool,
    /// A log-likelihood-ratio-like strength of the detection (≥ 0), for the diagnosis.
    pub strength: f64,
    /// What the effect changes, which decides how the diagnosis tests it against the base noise.
    pub signature: Signature,
}

impl Estimate {
    /// An effect located in time (a step, a burst): its values in schema order, without 1σ,
    /// reported as an event.
    pub fn event(values: Vec<f64>, strength: f64, signature: Signature) -> Self {
        Estimate { sigmas: vec![None; values.len()], values, is_event: true, strength, signature }
    }

    /// Coefficients (a regression's, a trend's) with their 1σ, in schema order.
    pub fn coefficients(values: Vec<f64>, sigmas: Vec<Option<f64>>, strength: f64, signature: Signature) -> Self {
        Estimate { values, sigmas, is_event: false, strength, signature }
    }
}

/// What a time-domain effect changes in the rate, which decides its test (see [`Whitened`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Signature {
    /// A bias that follows a measured driver (a regression on it).
    Driven,
    /// A step in the mean at one time (a scan over the time).
    MeanStep,
    /// A span with a louder white level (a scan over spans of block variances).
    WhiteLevel,
    /// A bias that drifts linearly in time (a GLS regression on time, [`trend`]).
    Trend,
}

/// The time-domain kinds sorted in estimation order
/// ([`estimation_rank`](crate::model::effects::TimeEstimator::estimation_rank); equal ranks, and
/// kinds without an estimator last, in the order given).
pub fn in_estimation_order(kinds: &[&'static dyn EffectKind]) -> Vec<&'static dyn EffectKind> {
    let rank = |k: &&'static dyn EffectKind| k.time_estimator().map_or(UNRANKED, |e| e.estimation_rank());
    let mut v = kinds.to_vec();
    v.sort_by_key(rank);
    v
}

/// True when the recording carries the evidence `kind` needs on this axis ([`Evidence`]).
pub fn has_evidence(kind: &dyn EffectKind, input: &AxisInput<'_>) -> bool {
    match kind.evidence() {
        Evidence::Temperature => input.temperature_c.is_some(),
        Evidence::Accel => input.accel.is_some() && input.axis.is_gyro(),
        Evidence::None | Evidence::Events => true,
    }
}

/// Estimates a time-domain effect on `series` (the axis's rate, with earlier effects removed), by
/// the kind's own [`TimeEstimator`](crate::model::effects::TimeEstimator).
///
/// # Errors
/// [`FitError::MissingEvidence`] without the driving signal; [`FitError::NoEstimator`] for a kind
/// without an estimator.
///
/// With `noise` (the base noise fitted to the rest), a regression is the GLS estimate against it;
/// without, the ordinary least-squares first guess. `fourth_cumulant` is the record's white
/// fourth cumulant ([`crate::allan::edf::white_fourth_cumulant`] of the rate as recorded, 0 when
/// Gaussian), which a search on sample-to-sample differences reads to leave isolated spikes out.
pub fn estimate(
    kind: &'static dyn EffectKind,
    input: &AxisInput<'_>,
    series: &[f64],
    noise: Option<&NoiseSpectrum>,
    fourth_cumulant: f64,
) -> Result<Estimate, FitError> {
    kind.time_estimator()
        .ok_or(FitError::NoEstimator(kind.id()))?
        .estimate(input, series, noise, fourth_cumulant)
}

/// Removes an estimated effect from `series`.
pub fn remove(kind: &dyn EffectKind, est: &Estimate, input: &AxisInput<'_>, series: &mut [f64]) {
    remove_values(kind, &est.values, input, series);
}

/// Removes an effect given by its values in schema order (a fitted term's) from `series`; a kind
/// without a time-domain estimator removes nothing.
pub fn remove_values(kind: &dyn EffectKind, v: &[f64], input: &AxisInput<'_>, series: &mut [f64]) {
    if let Some(own) = kind.time_estimator() {
        own.remove(v, input, series);
    }
}

/// Removes a driven bias from `series`: `coefficient` per unit of `driver` about its mean.
///
/// # Formula
/// ```text
/// y[n] −= c·(x[n] − x̄),   x̄ the mean of the finite x
/// ```
/// The temperature coefficient and the g-sensitivity are removed so (a missing driver value
/// makes the sample missing).
pub(crate) fn remove_driven(series: &mut [f64], driver: &[f64], coefficient: f64) {
    let mean = finite_mean(driver);
    series.iter_mut().zip(driver).for_each(|(y, x)| *y -= coefficient * (x - mean));
}

/// Mean of the finite values of `x`, 0 when there is none.
pub(crate) fn finite_mean(x: &[f64]) -> f64 {
    let (s, n) = x
        .iter()
        .filter(|v| v.is_finite())
        .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n > 0 {
        s / n as f64
    } else {
        0.0
    }
}

/// A least-squares line y = a + b·x through points added one at a time (Welford updates): the
/// whole-record regressions here and the node's live temperature coefficient share it.
///
/// # Formula
/// ```text
/// b = Sxy / Sxx,   σ_b² = (Syy − b·Sxy) / ((n − 2)·Sxx)
/// ```
/// with Sxx, Sxy, Syy the sums of products of deviations from the running means.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LineFit {
    n: u64,
    mean_x: f64,
    mean_y: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
}

impl LineFit {
    /// Adds the point (x, y).
    pub fn add(&mut self, x: f64, y: f64) {
        self.n += 1;
        let n = self.n as f64;
        let dx = x - self.mean_x;
        let dy = y - self.mean_y;
        self.mean_x += dx / n;
        self.mean_y += dy / n;
        self.sxx += dx * (x - self.mean_x);
        self.sxy += dx * (y - self.mean_y);
        self.syy += dy * (y - self.mean_y);
    }

    /// Points added.
    pub fn len(&self) -> u64 {
        self.n
    }

    /// True before the first point.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// (slope, its standard error), once there are three points and x moved.
    pub fn slope(&self) -> Option<(f64, f64)> {
        if self.n < 3 || self.sxx <= 0.0 {
            return None;
        }
        let b = self.sxy / self.sxx;
        let residual = (self.syy - b * self.sxy).max(0.0) / (self.n - 2) as f64;
        Some((b, (residual / self.sxx).sqrt()))
    }
}

/// Least-squares slope of `y` on `x` (both demeaned, NaN pairs skipped), its standard error, and
/// the squared t statistic (the strength): a [`LineFit`] through the pairs.
///
/// # Formula
/// ```text
/// c = Σ (x−x̄)(y−ȳ) / Σ (x−x̄)²,   se² = Σ r² / ((n−2)·Σ (x−x̄)²),   strength = (c/se)²
/// ```
pub fn regress(y: &[f64], x: &[f64]) -> (f64, f64, f64) {
    let mut line = LineFit::default();
    y.iter()
        .zip(x)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .for_each(|(&a, &b)| line.add(b, a));
    let Some((c, se)) = line.slope() else {
        return (0.0, f64::INFINITY, 0.0);
    };
    let strength = if se > 0.0 { (c / se).powi(2) } else { f64::INFINITY };
    (c, se, strength)
}

/// Least-squares slope between the first differences of coarse block means (record/20 per
/// block), its standard error corrected for the lag-1 autocorrelation ρ ≥ 0 of the residuals,
/// and the squared t statistic: the significance of a slow driver such as temperature.
///
/// Why differences: a temperature drifts over minutes, where the sensor's random walk lives too,
/// and a regression of one smooth curve on another has about one degree of freedom whatever the
/// number of samples (a "spurious regression"). Differencing turns a random walk into white
/// increments; the levels are kept for the coefficient itself (efficient when the effect is
/// strong), the differences only decide whether it is real.
///
/// # Formula
/// ```text
/// Δȳₖ = ȳₖ₊₁ − ȳₖ,  Δx̄ₖ = x̄ₖ₊₁ − x̄ₖ,   c = OLS slope of Δȳ on Δx̄
/// se_eff = se·√((1+ρ)/(1−ρ)),   strength = (c/se_eff)²
/// ```
pub fn regress_slow(y: &[f64], x: &[f64]) -> (f64, f64, f64) {
    let block = (y.len() / 20).max(1);
    let ym: Vec<f64> = y.chunks(block).map(finite_mean).collect();
    let xm: Vec<f64> = x.chunks(block).map(finite_mean).collect();
    let dy: Vec<f64> = ym.windows(2).map(|w| w[1] - w[0]).collect();
    let dx: Vec<f64> = xm.windows(2).map(|w| w[1] - w[0]).collect();
    let (c, se, _) = regress(&dy, &dx);
    let (mx, my) = (finite_mean(&dx), finite_mean(&dy));
    let r: Vec<f64> = dy.iter().zip(&dx).map(|(a, b)| (a - my) - c * (b - mx)).collect();
    let var: f64 = r.iter().map(|v| v * v).sum();
    let lag: f64 = r.windows(2).map(|w| w[0] * w[1]).sum();
    let rho = if var > 0.0 { (lag / var).clamp(0.0, 0.95) } else { 0.0 };
    let se_eff = se * ((1.0 + rho) / (1.0 - rho)).sqrt();
    let strength = if se_eff > 0.0 { (c / se_eff).powi(2) } else { 0.0 };
    (c, se_eff, strength)
}

/// The fitted base noise of an axis as the time-domain tests see it: a sum of power-law terms.
///
/// Why: a step, a temperature drift or a g-sensitivity is judged by how unlikely its estimate
/// would be under the noise the axis has — white rate noise, flicker and random walk — not under
/// white noise alone. With flicker and random walk a record wanders, and a white-noise test takes
/// the wander for a step or for a regression on any slow driver (a "spurious regression").
///
/// Each term is one [`NoiseClass`] with a coefficient `a` read from its Allan variance curve:
///
/// # Formula
/// ```text
/// class      σ²(τ)     rate PSD S(f), one-sided              rate structure D(τ) = E[(y(t+τ) − y(t))²]
/// white PM   3a/τ²     2a·τ0·(2 sin πfτ0)²/τ0²               4a/τ0²
/// white FM   a/τ       2a                                     2a/τ0
/// flicker    a         h/f,  h = a/(2 ln 2)                   2h·(ln(πτ/τ0) + γ)
/// RW FM      a·τ       3a/(2π²f²)                             3a·τ
/// ```
/// (NIST SP 1065 Table 6: σ² = h₀/(2τ), 2 ln2·h₋₁, (2π²/3)·h₋₂·τ; the flicker structure function
/// with the Nyquist frequency 1/(2τ0) as its upper cutoff, γ = 0.5772). `a` is the largest value
/// the curve implies over its τ grid: exact for a power law, and for a term that is none (a
/// Gauss–Markov bias counts as white FM, its long-τ asymptote) never below the term's power at
/// any τ, so the tests stay conservative.
///
/// # References
/// Riley W. J., NIST SP 1065 (2008), §5.2 and Table 6; IEEE Std 952-1997 Annex C.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseSpectrum {
    tau0: f64,
    parts: Vec<(NoiseClass, f64)>,
}

impl NoiseSpectrum {
    /// The spectrum of terms given as (class, σ²(τ) on `taus`), for samples `tau0` apart.
    pub fn from_curves<'a>(
        tau0: f64,
        taus: &[f64],
        terms: impl IntoIterator<Item = (NoiseClass, &'a [f64])>,
    ) -> Self {
        let parts = terms
            .into_iter()
            .map(|(class, curve)| {
                let a = taus
                    .iter()
                    .zip(curve)
                    .map(|(&t, &v)| match class {
                        NoiseClass::WhitePm => v * t * t / 3.0,
                        NoiseClass::WhiteFm => v * t,
                        NoiseClass::FlickerFm => v,
                        NoiseClass::RandomWalkFm => v / t,
                    })
                    .filter(|a| a.is_finite())
                    .fold(0.0, f64::max);
                (class, a)
            })
            .filter(|&(_, a)| a > 0.0)
            .collect();
        NoiseSpectrum { tau0, parts }
    }

    /// Allan variance at τ seconds.
    pub fn avar(&self, tau: f64) -> f64 {
        self.parts
            .iter()
            .map(|&(class, a)| match class {
                NoiseClass::WhitePm => 3.0 * a / (tau * tau),
                NoiseClass::WhiteFm => a / tau,
                NoiseClass::FlickerFm => a,
                NoiseClass::RandomWalkFm => a * tau,
            })
            .sum()
    }

    /// One-sided PSD of the rate at `f` Hz (0 < f ≤ 1/(2τ0)).
    pub fn rate_psd(&self, f: f64) -> f64 {
        self.rate_psd_with_gain(f, || self.difference_gain(f))
    }

    /// [`NoiseSpectrum::rate_psd`] with the difference gain at `f` given (white PM's rate is the
    /// difference of a white phase).
    fn rate_psd_with_gain(&self, f: f64, gain: impl Fn() -> f64) -> f64 {
        let tau0 = self.tau0;
        let pi = std::f64::consts::PI;
        self.parts
            .iter()
            .map(|&(class, a)| match class {
                NoiseClass::WhitePm => 2.0 * a * gain() / tau0,
                NoiseClass::WhiteFm => 2.0 * a,
                NoiseClass::FlickerFm => a / (2.0 * std::f64::consts::LN_2) / f,
                NoiseClass::RandomWalkFm => 3.0 * a / (2.0 * pi * pi) / (f * f),
            })
            .sum()
    }

    /// One-sided PSD of the rate's first differences, (2 sin πfτ0)²·S(f), at `f` Hz (its limit at
    /// f = 0: zero but for a random walk, whose differences are white).
    pub fn diff_psd(&self, f: f64) -> f64 {
        self.diff_psd_with_gain(f, self.difference_gain(f))
    }

    /// (2 sin πfτ0)²: the power gain of a first difference at `f` Hz.
    pub fn difference_gain(&self, f: f64) -> f64 {
        difference_gain(f, self.tau0)
    }

    /// [`NoiseSpectrum::diff_psd`] with the gain at `f` ([`NoiseSpectrum::difference_gain`])
    /// given: the same number, without its sine.
    fn diff_psd_with_gain(&self, f: f64, gain: f64) -> f64 {
        if f <= 0.0 {
            let tau0 = self.tau0;
            return self
                .parts
                .iter()
                .filter(|p| p.0 == NoiseClass::RandomWalkFm)
                .map(|&(_, a)| 6.0 * a * tau0 * tau0)
                .sum();
        }
        gain * self.rate_psd_with_gain(f, || gain)
    }

    /// Variance of the mean rate over the B = `b_s` seconds following a time minus that over the
    /// A = `a_s` seconds preceding it: 2σ²_A(W) when both are W.
    ///
    /// # Formula
    /// ```text
    /// var = D_θ(A)/A² + D_θ(B)/B² − (D_θ(A+B) − D_θ(A) − D_θ(B))/(AB)
    /// white PM   2a·(1/A² + 1/B² + 1/(AB))
    /// white FM   a·(1/A + 1/B)
    /// flicker    h·[((A+B)²·ln(A+B) − A²·ln A − B²·ln B)/(AB) − ln A − ln B],  h = a/(2 ln 2)
    /// RW FM      a·(A + B)
    /// ```
    /// with D_θ the angle's structure function of [`block_regression`] (flicker's infrared
    /// constant cancels; the random walk's rate is a Brownian motion of diffusion 3a, its means
    /// on the two sides independent given the value between them).
    pub fn contrast_variance(&self, a_s: f64, b_s: f64) -> f64 {
        self.parts
            .iter()
            .map(|&(class, a)| match class {
                NoiseClass::WhitePm => 2.0 * a * (1.0 / (a_s * a_s) + 1.0 / (b_s * b_s) + 1.0 / (a_s * b_s)),
                NoiseClass::WhiteFm => a * (1.0 / a_s + 1.0 / b_s),
                NoiseClass::FlickerFm => {
                    let xlnx = |x: f64| x * x * x.ln();
                    a / (2.0 * std::f64::consts::LN_2)
                        * ((xlnx(a_s + b_s) - xlnx(a_s) - xlnx(b_s)) / (a_s * b_s) - a_s.ln() - b_s.ln())
                }
                NoiseClass::RandomWalkFm => a * (a_s + b_s),
            })
            .sum()
    }

    /// Structure function of the rate, E[(y(t+τ) − y(t))²], at τ ≥ τ0.
    pub fn rate_structure(&self, tau: f64) -> f64 {
        let tau0 = self.tau0;
        self.parts
            .iter()
            .map(|&(class, a)| match class {
                NoiseClass::WhitePm => 4.0 * a / (tau0 * tau0),
                NoiseClass::WhiteFm => 2.0 * a / tau0,
                NoiseClass::FlickerFm => {
                    a / std::f64::consts::LN_2 * ((std::f64::consts::PI * tau / tau0).ln() + 0.577_215_664_9)
                }
                NoiseClass::RandomWalkFm => 3.0 * a * tau,
            })
            .sum()
    }

    /// How many times the Gaussian likelihood ratio of [`find_burst`] over-counts its degrees of
    /// freedom: the block variances sum squared first differences, which are correlated.
    ///
    /// # Formula
    /// ```text
    /// factor = 1 + 2·Σ_{h=1..8} ρ_Δ(h)²,   ρ_Δ(h) = ∫ S_Δ(f)·cos(2πfhτ0) df / ∫ S_Δ(f) df
    /// S_Δ(f) = (2 sin πfτ0)²·S(f)
    /// ```
    /// the variance of a sum of squares of a correlated Gaussian sequence over that of an
    /// independent one (ρ_Δ(1) = −½ for white noise: 1.5).
    pub fn burst_dof_factor(&self) -> f64 {
        const BINS: usize = 4096;
        let f_n = 0.5 / self.tau0;
        let spectrum: Vec<(f64, f64)> = (0..BINS)
            .map(|k| {
                let f = (k as f64 + 0.5) / BINS as f64 * f_n;
                (f, self.diff_psd(f))
            })
            .collect();
        let total: f64 = spectrum.iter().map(|p| p.1).sum();
        if total.is_nan() || total <= 0.0 {
            return 1.5;
        }
        let rho = |h: f64| {
            spectrum
                .iter()
                .map(|&(f, s)| s * (2.0 * std::f64::consts::PI * f * self.tau0 * h).cos())
                .sum::<f64>()
                / total
        };
        1.0 + 2.0 * (1..=8).map(|h| rho(h as f64).powi(2)).sum::<f64>()
    }
}

/// A regression coefficient with its standard error under the base noise, and t².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Regression {
    /// Coefficient, SI.
    pub coefficient: f64,
    /// Its 1σ under the base noise.
    pub sigma: f64,
    /// (coefficient/σ)²: χ²₁ when there is no effect.
    pub t2: f64,
}

/// The first differences of a rate series, tapered, Fourier transformed and weighted by the base
/// noise: generalised least squares in the frequency domain (Whittle's approximation of the
/// Gaussian likelihood).
///
/// Why the frequency domain: the Fourier coefficients of stationary noise are nearly independent
/// with variance ∝ S(f), so the GLS fit of any driver — a slow temperature or a fast vibration —
/// costs one transform. Why first differences: a random walk's differences are stationary (its
/// levels are not, and their transform is dominated by the record's end-to-start jump). Why a
/// taper: the differences of a finite record still jump at the wrap-around (their sum is the rate's
/// end minus its start), which a plain transform spreads over every bin as a constant — and the
/// differences of white noise have almost no power at low frequencies, so that constant buries
/// them. The Hann taper's three Fourier taps (½, −¼, −¼) cancel a constant across bins exactly.
/// The price is known: tapered coefficients correlate with their neighbours, which the variance
/// below includes. Differencing is invertible up to a constant, so the GLS estimate loses nothing
/// (an ordinary regression on differences would discard a slow driver).
///
/// # Formula
/// ```text
/// Y_k = DFT(h·Δy)_k,  X_k likewise for the driver,  h_j = sin²(π(j+½)/n)
/// s_m = n·S_Δ(f_m)/(2τ0),   S_Δ(f) = (2 sin πfτ0)²·S(f)     (untapered variance)
/// C_kk = s_k/4 + (s_{k−1} + s_{k+1})/16,  C_k,k+1 = −(s_k + s_{k+1})/8,  C_k,k+2 = s_{k+1}/16
/// a_k = X_k / C_kk,   c = Σ Re(a_k* Y_k) / Σ Re(a_k* X_k)
/// var(c) = ½·Re Σ_{k,l} a_k* C_kl a_l / (Σ Re(a_k* X_k))²
/// ```
///
/// # References
/// Whittle P., "Curve and periodogram smoothing", JRSS B 19(1), 1957; Percival D. B. & Walden
/// A. T., Spectral Analysis for Physical Applications, CUP 1993, §6.4 (tapers) and §9.
///
/// Only the newest [`fast_len`] differences are transformed (at most 1 % of the record left out
/// at its start, see [`fast_len`]): a transform of arbitrary length goes through Bluestein's algorithm, whose
/// power-of-two inner transform of ≥ 2n points, chirp and scratch took 405 MB for one axis of a
/// 1.57 M-sample record; a length with small prime factors is transformed in place.
pub struct Whitened {
    noise: NoiseSpectrum,
    /// Samples left out at the start of the series (and of every driver).
    skip: usize,
    len: usize,
    /// The transform of `len` points and its taper, made once: a driver's has the same length.
    plan: Plan,
    /// The transform of the tapered differences: shared by the weightings of one series
    /// ([`Whitened::with_noise`]), as long as the series itself.
    spectrum: Arc<Vec<Complex<f64>>>,
    /// s_m of the formula, m = 0 … ⌈n/2⌉.
    untapered: Vec<f64>,
    /// The difference gain at each s_m's frequency ([`DifferenceGains`]): shared by the weightings
    /// of one series, and by the axes of a record.
    gains: DifferenceGains,
}

impl std::fmt::Debug for Whitened {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Whitened").field("skip", &self.skip).field("len", &self.len).finish_non_exhaustive()
    }
}

impl Whitened {
    /// Transforms the first differences of `y` (a non-finite sample holds the last finite value) and weights
    /// them by `noise`. `None` for fewer than 16 samples or a spectrum without power.
    pub fn new(y: &[f64], noise: &NoiseSpectrum) -> Option<Self> {
        Self::planned(y, noise, &Plans::default())
    }

    /// [`Whitened::new`] with its transform planned by `plans` (shared by the axes of a record).
    pub fn planned(y: &[f64], noise: &NoiseSpectrum, plans: &Plans) -> Option<Self> {
        if y.len() < 17 {
            return None;
        }
        let len = fast_len(y.len() - 1);
        let skip = y.len() - 1 - len;
        let plan = plans.forward(len);
        let spectrum = Arc::new(tapered_diff_dft(&y[skip..], &plan));
        let gains = plans.difference_gains(len, noise.tau0);
        Self::weighted(skip, len, plan, spectrum, gains, noise)
    }

    /// The same series weighted by another base noise: what [`Whitened::new`] gives on the same
    /// `y`, without transforming it again.
    pub fn with_noise(&self, noise: &NoiseSpectrum) -> Option<Self> {
        let gains = if self.gains.tau0.to_bits() == noise.tau0.to_bits() {
            self.gains.clone()
        } else {
            DifferenceGains::new(self.len, noise.tau0)
        };
        Self::weighted(self.skip, self.len, self.plan.clone(), Arc::clone(&self.spectrum), gains, noise)
    }

    fn weighted(
        skip: usize,
        len: usize,
        plan: Plan,
        spectrum: Arc<Vec<Complex<f64>>>,
        gains: DifferenceGains,
        noise: &NoiseSpectrum,
    ) -> Option<Self> {
        debug_assert_eq!(gains.at.len(), spectrum.len() + 1);
        let untapered: Vec<f64> = (0..gains.at.len()).map(|m| gains.untapered(noise, len, m)).collect();
        if untapered.iter().skip(1).any(|s| !(s.is_finite() && *s > 0.0)) {
            return None;
        }
        Some(Whitened { noise: noise.clone(), skip, len, plan, spectrum, untapered, gains })
    }

    /// The base noise the series is weighted by.
    pub fn noise(&self) -> &NoiseSpectrum {
        &self.noise
    }

    /// Covariance of tapered coefficients k and k + d (d = 0, 1, 2).
    fn cov(&self, k: usize, d: usize) -> f64 {
        let s = |m: usize| self.untapered.get(m).copied().unwrap_or(0.0);
        match d {
            0 => s(k) / 4.0 + (s(k - 1) + s(k + 1)) / 16.0,
            1 => -(s(k) + s(k + 1)) / 8.0,
            2 => s(k + 1) / 16.0,
            _ => 0.0,
        }
    }

    /// GLS regression of the rate on a driver `x` (one value per rate sample).
    pub fn regress(&self, x: &[f64]) -> Option<Regression> {
        let g = self.gls(x)?;
        let coefficient = g.num / g.den;
        let sigma = g.var_num.sqrt() / g.den;
        Some(Regression { coefficient, sigma, t2: (coefficient / sigma).powi(2) })
    }

    /// [`Whitened::regress`] on a driver measured with white noise of its own (an accelerometer
    /// axis), its coefficient corrected for the attenuation that noise causes.
    ///
    /// Why: the driver's noise adds its power to the denominator and nothing to the numerator,
    /// so the slope shrinks by that noise's share of the weighted driver power (errors in
    /// variables; measured: −11 % for a 0.5 m/s² motion at 200 Hz under 6.3·10⁻³ m/s²/√Hz of accel
    /// white noise, where the test's 1σ was 4 %). The corrected score subtracts the noise's
    /// expected share, its level read from the upper half of the band, where the median ignores a
    /// vibration line.
    ///
    /// # Formula
    /// ```text
    /// â_u = median over k ≥ K/2 of |X_k|²/U_kk / ln 2     (U: C of white FM with a = 1)
    /// den' = Σ Re(a_k* X_k) − â_u·Σ U_kk/C_kk,   c = num/den'
    /// var(c) = ½·(Re Σ a_k* C_kl a_l + c²·â_u·Σ |a_k|² U_kk) / den'²
    /// ```
    /// where K is the number of bins and ln 2 the median of a unit exponential. The correction is
    /// applied only while it is under half of the plain denominator (else the driver is mostly
    /// noise, or a broadband motion fills the upper band, and the plain estimate is returned).
    ///
    /// # References
    /// Nakamura T., "Corrected score function for errors-in-variables models", Biometrika 77(1),
    /// 1990; Fuller W. A., Measurement Error Models, Wiley 1987, §1.1 (attenuation).
    pub fn regress_measured(&self, x: &[f64]) -> Option<Regression> {
        let g = self.gls(x)?;
        let unit = NoiseSpectrum { tau0: self.noise.tau0, parts: vec![(NoiseClass::WhiteFm, 1.0)] };
        let u = |m: usize| self.gains.untapered(&unit, self.len, m);
        let bins = g.xs.len();
        let u_kk = |k: usize| u(k) / 4.0 + (u(k - 1) + u(k + 1)) / 16.0;
        let mut ratios: Vec<f64> = (bins / 2..bins).map(|k| g.xs[k].norm_sqr() / u_kk(k)).collect();
        if ratios.is_empty() {
            return self.regress(x);
        }
        let mid = ratios.len() / 2;
        let a_u = *ratios.select_nth_unstable_by(mid, f64::total_cmp).1 / std::f64::consts::LN_2;
        let correction = a_u * (1..bins).map(|k| u_kk(k) / self.cov(k, 0)).sum::<f64>();
        if !(correction.is_finite() && correction >= 0.0 && correction < 0.5 * g.den) {
            return self.regress(x);
        }
        let den = g.den - correction;
        let coefficient = g.num / den;
        let extra = coefficient.powi(2) * a_u * (1..bins).map(|k| self.weight(&g.xs, k).norm_sqr() * u_kk(k)).sum::<f64>();
        let sigma = (g.var_num + 0.5 * extra).sqrt() / den;
        Some(Regression { coefficient, sigma, t2: (coefficient / sigma).powi(2) })
    }

    /// A line's evidence near `f` Hz: the strongest ordinate of the weighted periodogram within
    /// [`line_reach`] bins of `f` (two, or 10 % of f when that is more), leaving out the bins
    /// within one more than that of any frequency in `taken` (lines the model already holds).
    /// `None` when no bin is left.
    ///
    /// Why: a line's Allan bump sits at τ ≈ 0.37/f, where a record of a few periods has few
    /// degrees of freedom; its Fourier power does not spread. A line 32× the base Allan variance
    /// at its peak, 3 periods in a 20 min record, gained a χ² of 17.6 on the Allan variance
    /// (threshold 18) while its bin held far more than the base noise's power.
    ///
    /// # Formula
    /// ```text
    /// r = max over |k − f·n·τ0| ≤ reach(f) of |Y_k|²/C_kk,   p = min(1, K·e^(−r))
    /// ```
    /// with Y_k and C_kk those of the GLS ([`Whitened`]). Under the base noise each Y_k is complex
    /// Gaussian of variance C_kk, so |Y_k|²/C_kk is a unit exponential; p is the Bonferroni bound
    /// over the K bins of the transform, which holds whatever chose `f` (Fisher's test of a
    /// hidden periodicity, here against a coloured noise).
    ///
    /// # References
    /// Fisher R. A., "Tests of significance in harmonic analysis", Proc. R. Soc. A 125, 1929;
    /// Percival & Walden 1993, §10.9 (tests for periodicity in coloured noise).
    pub fn line_power(&self, f: f64, taken: &[f64]) -> Option<LinePower> {
        let bins = self.spectrum.len();
        let per_hz = self.len as f64 * self.noise.tau0;
        let (centre, reach) = (f * per_hz, line_reach(f, per_hz));
        if !(centre.is_finite() && centre > 0.0) {
            return None;
        }
        let first = (centre - reach).ceil().max(1.0) as usize;
        let last = ((centre + reach).floor() as usize).min(bins.saturating_sub(2));
        let statistic = (first..=last)
            .filter(|&k| taken.iter().all(|&g| (k as f64 - g * per_hz).abs() > line_reach(g, per_hz) + 1.0))
            .map(|k| self.spectrum[k].norm_sqr() / self.cov(k, 0))
            .filter(|r| r.is_finite())
            .max_by(f64::total_cmp)?;
        Some(LinePower { statistic, bins: bins as f64 })
    }

    /// The sums of the GLS regression on `x`: numerator, denominator and the numerator's variance
    /// (see the formula of [`Whitened`]), with the driver's transform.
    fn gls(&self, x: &[f64]) -> Option<Gls> {
        if x.len() != self.skip + self.len + 1 {
            return None;
        }
        let xs = tapered_diff_dft(&x[self.skip..], &self.plan);
        let bins = xs.len();
        // One pass, each weight a_k computed once and held while the two bins after it need it
        // (not stored: a whole-run record's driver transform is millions of bins); each sum adds
        // the same terms in the same order as a pass of its own.
        let zero = Complex::new(0.0, 0.0);
        let weight = |k: usize| if k < bins { self.weight(&xs, k) } else { zero };
        let (mut a, mut a1, mut a2) = (weight(1), weight(2), weight(3));
        let (mut num, mut den, mut var) = (0.0, 0.0, 0.0);
        for (k, (x_k, y_k)) in xs.iter().zip(self.spectrum.iter()).enumerate().skip(1) {
            num += (a.conj() * y_k).re;
            den += (a.conj() * x_k).re;
            let mut v = a.norm_sqr() * self.cov(k, 0);
            for (d, next) in [(1, a1), (2, a2)] {
                if k + d < bins {
                    v += 2.0 * (a.conj() * next).re * self.cov(k, d);
                }
            }
            var += v;
            (a, a1, a2) = (a1, a2, weight(k + 3));
        }
        if den.is_nan() || den <= 0.0 {
            return None;
        }
        let var_num = 0.5 * var;
        if var_num.is_nan() || var_num <= 0.0 {
            return None;
        }
        Some(Gls { num, den, var_num, xs })
    }

    /// The GLS weight of bin `k` of a driver's transform `xs`: a_k = X_k / C_kk (0 for the mean).
    fn weight(&self, xs: &[Complex<f64>], k: usize) -> Complex<f64> {
        if k == 0 {
            Complex::new(0.0, 0.0)
        } else {
            xs[k] / self.cov(k, 0)
        }
    }
}

/// The evidence of [`Whitened::line_power`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinePower {
    /// The strongest |Y_k|²/C_kk near the line: a unit exponential per bin under the base noise.
    pub statistic: f64,
    /// Bins of the transform, the Bonferroni count.
    pub bins: f64,
}

impl LinePower {
    /// The p-value of a statistic `r`: min(1, bins·e^(−r)).
    pub fn p_at(&self, r: f64) -> f64 {
        (self.bins * (-r).exp()).min(1.0)
    }
}

/// The sums of one GLS regression ([`Whitened::gls`]).
struct Gls {
    num: f64,
    den: f64,
    var_num: f64,
    xs: Vec<Complex<f64>>,
}

/// Blocks of [`trend`]: a line through M block means keeps all but 1/M² of the record's trend
/// information under white noise, and the GLS solve on them is cheap.
const TREND_BLOCKS: usize = 128;

/// GLS slope of the rate on time (a linear drift, rate per second) under the base noise `noise`,
/// from the means of equal blocks with their covariance under each power law.
///
/// Why not [`Whitened::regress`] on x = t: a trend's first differences are a constant, which the
/// Hann taper cancels by design (it is there for the end-to-start jump), so the whitened
/// differences keep almost nothing of a trend — and a random walk's own drift over the record is
/// exactly what a trend must be told from. Block means keep all of a line, and their covariance
/// is exact for each class. The newest M·b samples are used; a block less than half finite is
/// left out.
///
/// # Formula
/// ```text
/// m_j = mean of block j (b samples, τb = b·τ0),  t_j its centre,  d = |j − k|
/// C_jk = Σ over terms:
///   white PM (a):   2a/τb² (d = 0),  −a/τb² (d = 1)
///   white FM (a):   a/τb (d = 0)
///   flicker FM (a): a/(2 ln 2)·(L − h(d)/2),  h(d) = (d+1)² ln(d+1) + (d−1)² ln|d−1| − 2d² ln d
///   RW FM (a):      3a·τb·(min(j, k) + ½)  (j ≠ k),  3a·τb·(j + ⅓)  (j = k)
/// [c₀, r] = (XᵀC⁻¹X)⁻¹XᵀC⁻¹m,  X = [1, t_j],  σ_r² = [(XᵀC⁻¹X)⁻¹]₁₁,  t² = (r/σ_r)²
/// ```
/// with `a` each term's Allan coefficient ([`NoiseSpectrum`]). Each block mean is an increment of
/// the angle θ over τb, so C_jk = [D_θ((d+1)τb) + D_θ(|d−1|τb) − 2D_θ(dτb)]/(2τb²) with the
/// angle's structure function D_θ: 2a (white PM), a·τ (white FM), a/(2 ln 2)·τ²·(L − ln τ)
/// (flicker FM, NIST SP 1065 Table 6). The random walk has no stationary increments of θ; its
/// rate is a Brownian motion of diffusion 3a from the first block (E[(y(t+τ) − y(t))²] = 3aτ),
/// its start absorbed by the intercept c₀, as flicker's infrared constant L is (adding a constant
/// to every C_jk leaves the slope unchanged when X holds the constant column); L = ln M + 3 keeps
/// C positive definite. Checks: C₀₀ − C₀₁ = σ²(τb) for every class.
///
/// # References
/// Riley W. J., NIST SP 1065 (2008), Table 6; Kariya T. & Kurata H., Generalized Least Squares,
/// Wiley 2004, §2 (GLS, and the invariance under a random intercept).
pub fn trend(y: &[f64], noise: &NoiseSpectrum) -> Option<Regression> {
    block_gls(y, Regressor::Time, noise)
}

/// GLS size of a step in the rate at sample `at` (the same block means and covariance as
/// [`trend`]; the regressor of a block is the share of its finite samples at or after `at`).
/// `None` as [`trend`].
///
/// Why not the scan's two-window contrast: it reads 2W samples of the record and weighs them
/// alike; GLS reads every block, weighed by the noise between them. Under white noise the
/// contrast's variance is 2σ²/W against σ²(1/n₁ + 1/n₂) for GLS, and under a random walk both
/// come down to the blocks next to the step. Measured on steps at 12 σ of the scan's test
/// (`diagnosis_power -- power 100 13 - bias_step`): the size within 10 % on 62 of 97 detected
/// with the contrast (of `find_step`), on 74 by GLS; the step's time is the scan's in both.
pub fn step_size(y: &[f64], at: usize, noise: &NoiseSpectrum) -> Option<Regression> {
    block_gls(y, Regressor::StepAt(at), noise)
}

/// [`trend`] with the block means of a driver `x` (one value per rate sample; a block is used
/// when both its rate and its driver are at least half finite) in place of the block times:
/// the slope of the rate on `x`, from the same block means and covariance. `None` as [`trend`].
///
/// Why: a slow driver (a warm-up) and a line in time are told apart by which of the two
/// explains the block means better, each fitted the same way against the same noise.
pub fn block_regression(y: &[f64], x: Option<&[f64]>, noise: &NoiseSpectrum) -> Option<Regression> {
    block_gls(y, x.map_or(Regressor::Time, Regressor::Driver), noise)
}

/// What the block means of [`block_gls`] are regressed on.
#[derive(Clone, Copy)]
enum Regressor<'a> {
    /// The block's centre time (a trend).
    Time,
    /// The block mean of a driver, one value per rate sample.
    Driver(&'a [f64]),
    /// The share of the block's finite samples at or after a sample (a step there).
    StepAt(usize),
}

/// The GLS coefficient of the rate's block means on `regressor` ([`trend`]'s formula).
fn block_gls(y: &[f64], regressor: Regressor<'_>, noise: &NoiseSpectrum) -> Option<Regression> {
    if matches!(regressor, Regressor::Driver(x) if x.len() != y.len()) {
        return None;
    }
    let m = TREND_BLOCKS.min(y.len() / 8);
    if m < 8 {
        return None;
    }
    let b = y.len() / m;
    let skip = y.len() - m * b;
    let tau0 = noise.tau0;
    let tb = b as f64 * tau0;
    let finite = |v: &[f64]| v.iter().filter(|v| v.is_finite()).count();
    // The mean of a block at least half finite (else the block is left out).
    let block_mean = |v: &[f64]| (2 * finite(v) >= v.len()).then(|| finite_mean(v));
    // (block index, regressor: centre time, driver mean or the step's share, rate mean) of the
    // blocks at least half finite.
    let blocks: Vec<(usize, f64, f64)> = (0..m)
        .filter_map(|j| {
            let start = skip + j * b;
            let block = &y[start..start + b];
            let mean = block_mean(block)?;
            let regressor = match regressor {
                Regressor::Time => (start as f64 + 0.5 * (b as f64 - 1.0)) * tau0,
                Regressor::Driver(x) => block_mean(&x[start..start + b])?,
                Regressor::StepAt(at) => {
                    finite(&block[at.clamp(start, start + b) - start..]) as f64 / finite(block) as f64
                }
            };
            Some((j, regressor, mean))
        })
        .collect();
    let k = blocks.len();
    if k < 4 {
        return None;
    }
    let big_l = (m as f64).ln() + 3.0;
    let xlnx = |x: f64| if x > 0.0 { x * x * x.ln() } else { 0.0 };
    let cov = |j: usize, l: usize| -> f64 {
        let d = j.abs_diff(l) as f64;
        noise
            .parts
            .iter()
            .map(|&(class, a)| match class {
                NoiseClass::WhitePm if d == 0.0 => 2.0 * a / (tb * tb),
                NoiseClass::WhitePm if d == 1.0 => -a / (tb * tb),
                NoiseClass::WhiteFm if d == 0.0 => a / tb,
                NoiseClass::WhitePm | NoiseClass::WhiteFm => 0.0,
                NoiseClass::FlickerFm => {
                    let h = xlnx(d + 1.0) + xlnx((d - 1.0).abs()) - 2.0 * xlnx(d);
                    a / (2.0 * std::f64::consts::LN_2) * (big_l - 0.5 * h)
                }
                NoiseClass::RandomWalkFm if d == 0.0 => 3.0 * a * tb * (j as f64 + 1.0 / 3.0),
                NoiseClass::RandomWalkFm => 3.0 * a * tb * (j.min(l) as f64 + 0.5),
            })
            .sum()
    };
    let c = DMatrix::from_fn(k, k, |r, s| cov(blocks[r].0, blocks[s].0));
    let chol = c.cholesky()?;
    let t_mid = blocks.iter().map(|b| b.1).sum::<f64>() / k as f64;
    let design = DMatrix::from_fn(k, 2, |r, col| if col == 0 { 1.0 } else { blocks[r].1 - t_mid });
    let means = DVector::from_iterator(k, blocks.iter().map(|b| b.2));
    let cx = chol.solve(&design);
    let normal = design.transpose() * &cx;
    let rhs = cx.transpose() * means;
    let inv = normal.try_inverse()?;
    let slope = (inv.row(1) * rhs)[0];
    let var = inv[(1, 1)];
    if !(var.is_finite() && var > 0.0 && slope.is_finite()) {
        return None;
    }
    let sigma = var.sqrt();
    Some(Regression { coefficient: slope, sigma, t2: (slope / sigma).powi(2) })
}

/// Forward FFT plans and Hann tapers by length, shared by the diagnoses of one record's axes.
///
/// Why: planning a transform (its twiddle factors) can cost as much as the transform itself, and
/// a taper costs a sine per point (7 % of a diagnosis when made per transform); every axis of a
/// record has the same length. Both depend on the length only, so shared ones give the same
/// numbers.
pub struct Plans(Mutex<Made>);

/// What [`Plans`] made so far: the planner (which keeps its plans) and the tapers by length.
#[derive(Default)]
struct Made {
    planner: RealFftPlanner<f64>,
    tapers: HashMap<usize, Arc<[f64]>>,
    /// By length and τ0's bits.
    gains: HashMap<(usize, u64), DifferenceGains>,
}

impl Default for Plans {
    fn default() -> Self {
        Plans(Mutex::new(Made::default()))
    }
}

/// A forward real-to-complex transform of n points and the Hann taper of the n differences it
/// transforms.
#[derive(Clone)]
pub struct Plan {
    fft: Arc<dyn RealToComplex<f64>>,
    taper: Arc<[f64]>,
}

/// The index of the sample at `time_s` seconds from the first, on a grid of `tau0` s: how a
/// time-domain estimate's time (a step's, a burst's ends) is placed back on the series.
pub fn index_at(time_s: f64, tau0: f64) -> usize {
    (time_s / tau0).round() as usize
}

/// (2 sin πfτ0)²: the power gain at `f` Hz of a first difference of samples `tau0` s apart.
fn difference_gain(f: f64, tau0: f64) -> f64 {
    (2.0 * (std::f64::consts::PI * f * tau0).sin()).powi(2)
}

/// (2 sin πf_mτ0)², the power gain of a first difference, at the frequencies f_m = m/(nτ0) of a
/// transform of n differences, m = 0 … ⌊n/2⌋ + 1 (one past its last bin: the weighting's s_m reach
/// it, [`Whitened::cov`]) ([`NoiseSpectrum::difference_gain`]).
///
/// Why kept: a weighting ([`Whitened`]) needs one per frequency, and a sine per point was most of
/// a weighting's cost; the diagnosis weights one series several times (each candidate's noise),
/// and every axis of a record has the same n and τ0. The same numbers as a sine each time.
#[derive(Clone)]
struct DifferenceGains {
    tau0: f64,
    at: Arc<[f64]>,
}

impl DifferenceGains {
    fn new(len: usize, tau0: f64) -> DifferenceGains {
        let at = (0..=len / 2 + 1).map(|m| difference_gain(Self::frequency(m, len, tau0), tau0)).collect();
        DifferenceGains { tau0, at }
    }

    /// f_m, Hz.
    fn frequency(m: usize, len: usize, tau0: f64) -> f64 {
        m as f64 / (len as f64 * tau0)
    }

    /// s_m of [`Whitened`]'s formula for `noise` (of these gains' τ0) on a transform of `len`
    /// differences: n·S_Δ(f_m)/(2τ0), S_Δ the PSD of the differences.
    fn untapered(&self, noise: &NoiseSpectrum, len: usize, m: usize) -> f64 {
        debug_assert_eq!(self.tau0.to_bits(), noise.tau0.to_bits());
        let f = Self::frequency(m, len, noise.tau0);
        len as f64 * noise.diff_psd_with_gain(f, self.at[m]) / (2.0 * noise.tau0)
    }
}

impl std::fmt::Debug for Plans {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Plans").finish_non_exhaustive()
    }
}

impl Plans {
    /// The forward real-to-complex transform of `len` points and its taper (made once per length).
    pub fn forward(&self, len: usize) -> Plan {
        // A planner is left consistent by a panic elsewhere: its caches only ever gain entries.
        let mut made = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        let Made { planner, tapers, .. } = &mut *made;
        let taper = tapers.entry(len).or_insert_with(|| {
            (0..len)
                .map(|j| (std::f64::consts::PI * (j as f64 + 0.5) / len as f64).sin().powi(2))
                .collect()
        });
        Plan { taper: Arc::clone(taper), fft: planner.plan_fft_forward(len) }
    }

    /// The difference gains of a transform of `len` differences sampled every `tau0` s (made
    /// once per length and period).
    fn difference_gains(&self, len: usize, tau0: f64) -> DifferenceGains {
        let mut made = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        made.gains.entry((len, tau0.to_bits())).or_insert_with(|| DifferenceGains::new(len, tau0)).clone()
    }

    /// The forward real-to-complex transform of `len` points alone (made once per length), for a
    /// transform without the taper (`fit::Periodogram`).
    pub fn transform(&self, len: usize) -> Arc<dyn RealToComplex<f64>> {
        let mut made = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        made.planner.plan_fft_forward(len)
    }
}

/// The largest even n' ≤ `n` whose prime factors are at most 13 (a few excepted): a length whose
/// real transform (a complex one of n'/2 points) rustfft does by mixed radix with its butterflies,
/// in place, with no scratch (see `is_fast`). Such lengths
/// lie at most 1 % apart above 2·10⁴ (0.3 % above 2·10⁶, 2 % above 2·10³), so little of a record
/// is left out; below 64 every length is kept.
pub fn fast_len(n: usize) -> usize {
    if n < 64 {
        return n;
    }
    (1..=n / 2).rev().find(|&m| is_fast(m)).map_or(n, |m| 2 * m)
}

/// `m`'s prime factors are all at most 13, and it is not 13ᵏ·c with k ≥ 2 and c ≤ 4.
///
/// Why not those: rustfft (6.4) transforms them by Bluestein's algorithm, whose scratch is an inner
/// transform longer than the length itself (measured with realfft 3.5 over every even 13-smooth
/// length from 64 to 2.4·10⁶: exactly 2·13ᵏ·{1, 2, 3, 4}, k = 2 … 5, need scratch; 2·2·13⁵ needs
/// 1.49·10⁶ values; every other length needs none). A record of such a length made its diagnosis
/// round 24 MB larger than its neighbours' (`cargo bench --bench node_soak -- in-process 24
/// 1800`: the round at 17 h).
fn is_fast(m: usize) -> bool {
    let (mut rest, mut thirteens) = (m, 0);
    while rest > 0 && rest.is_multiple_of(13) {
        rest /= 13;
        thirteens += 1;
    }
    if thirteens >= 2 && rest <= 4 {
        return false;
    }
    for p in [2, 3, 5, 7, 11] {
        while rest > 0 && rest.is_multiple_of(p) {
            rest /= p;
        }
    }
    rest == 1
}

/// DFT of the first differences of `y`, Hann-tapered (a non-finite sample holds the last finite value:
/// its differences are 0 and the increment across it goes to the next one),
/// bins 0 … ⌈(n−1)/2⌉−1, by `plan` (made for n − 1 points). Their mean is kept: it is the
/// end-minus-start jump that the taper cancels (removing it would leave −¼ of the jump in bin 1).
///
/// Why hold, not the series' mean: on a wandering axis a sample read as the mean is a jump there
/// and back, and samples missing on every axis at once (a lost message, a gap) put those jumps at
/// the same places on the gyro and on the accelerometer — a driver regression then finds them
/// (measured: g-sensitivity on all three gyro axes of the 24 h soak recording).
///
/// Why a real-to-complex transform: the differences are real, so half the spectrum is the
/// other's conjugate; computing only that half takes half the memory of a complex transform.
fn tapered_diff_dft(y: &[f64], plan: &Plan) -> Vec<Complex<f64>> {
    let (n, fft) = (y.len().saturating_sub(1), &plan.fft);
    let mut held = y.iter().copied().find(|v| v.is_finite()).unwrap_or(0.0);
    debug_assert_eq!(plan.taper.len(), n);
    let mut d: Vec<f64> = if y.iter().all(|v| v.is_finite()) {
        // The usual record: the same differences without the holding, in a loop the compiler
        // lays out as vectors.
        y.windows(2).zip(plan.taper.iter()).map(|(w, h)| (w[1] - w[0]) * h).collect()
    } else {
        y.windows(2)
            .zip(plan.taper.iter())
            .map(|(w, h)| {
                if w[0].is_finite() {
                    held = w[0];
                }
                let v = if w[1].is_finite() { w[1] - held } else { 0.0 };
                v * h
            })
            .collect()
    };
    debug_assert_eq!(fft.len(), n);
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut d, &mut spectrum)
        .expect("buffers made for this plan's length");
    spectrum.truncate(n.div_ceil(2));
    spectrum
}

/// The best single step in the mean, scanned over every time, against the base noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepScan {
    /// First sample after the best step.
    pub index: usize,
    /// The contrast there, SI.
    pub size: f64,
    /// 1σ of the contrast under the base noise.
    pub sigma: f64,
    /// (size/σ)² at the best time.
    pub t2: f64,
    /// Probability that the base noise alone gives a maximum this large.
    pub p_value: f64,
    /// Window, samples.
    pub window: usize,
    positions: f64,
    lambda2: f64,
    /// Contrasts tested at the ends besides the scan ([`STEP_END_SPLITS`] per end).
    end_positions: f64,
}

impl StepScan {
    /// The probability of the scan's maximum reaching `t2` under the base noise (the bound of
    /// [`step_scan`]).
    pub fn p_at(&self, t2: f64) -> f64 {
        let t2 = t2.max(0.0);
        let tail = erfc((t2 / 2.0).sqrt());
        let rice = tail
            + 2.0 * self.positions * self.lambda2.sqrt() / (2.0 * std::f64::consts::PI) * (-0.5 * t2).exp();
        ((self.positions * tail).min(rice) + self.end_positions * tail).min(1.0)
    }
}

/// Shorter windows at each end of the record for [`step_scan`]: W/2, W/4, … W/2^k on the side
/// that has less than W. Why: the scan compares two full windows, so a step within W of either
/// end had none on one side (docs/model-measurements.md, "Known limits that were fixed": at 12 s
/// and 36 s of 20 min, 0 of 3).
const STEP_END_SPLITS: u32 = 4;

/// Longest and shortest step windows, as fractions of the record.
const STEP_WINDOW_RANGE: (f64, f64) = (1.0 / 60.0, 1.0 / 6.0);

/// The window of [`step_scan`] for `n` samples: where the Allan variance of `noise` is least,
/// between record/60 and record/6 (40 candidates, log-spaced).
pub fn step_window(n: usize, noise: &NoiseSpectrum) -> usize {
    let (lo, hi) = (
        ((n as f64 * STEP_WINDOW_RANGE.0) as usize).max(2),
        ((n as f64 * STEP_WINDOW_RANGE.1) as usize).max(2),
    );
    (0..=40)
        .map(|k| (lo as f64 * (hi as f64 / lo as f64).powf(k as f64 / 40.0)).round() as usize)
        .min_by(|&a, &b| noise.avar(a as f64 * noise.tau0).total_cmp(&noise.avar(b as f64 * noise.tau0)))
        .unwrap_or(lo)
}

/// The step contrast of [`find_step`] scanned over every time, with the window where the base
/// noise lets a step show most, tested against that noise.
///
/// The contrast D(i) = mean(y[i..i+W]) − mean(y[i−W..i]) has variance 2σ²_A(W·τ0) under any
/// stationary noise (it *is* the Allan difference at τ = W·τ0), so the window where the fitted
/// Allan variance is least (the bias-instability floor, between the white and random-walk
/// slopes) is where a step stands out most; W is searched over record/60 … record/6.
///
/// # Formula
/// ```text
/// t²(i) = D(i)² / (2σ²_A(Wτ0) · W / min(c₁, c₂)),   t² = max over W ≤ i ≤ n − W
/// λ₂ = var(D(i+1) − D(i)) / var(D) = (4·D_y(Wτ0) − D_y(2Wτ0)) / (W²·2σ²_A(Wτ0))
/// p = min(M·P(|Z| > t),  P(|Z| > t) + 2M·(√λ₂/2π)·e^{−t²/2}),   M = n − 2W
/// ```
/// with D_y the rate's structure function ([`NoiseSpectrum::rate_structure`]): Rice's formula for
/// the up-crossings of ±t by the standardised scan (λ₂ its second spectral moment per sample²),
/// capped by the Bonferroni bound over the M times. Both are upper bounds, so the test is
/// conservative where the scan is rough (white noise: the Brownian scan crosses far less often than
/// its sample-to-sample roughness claims).
///
/// # References
/// Rice S. O., "Mathematical analysis of random noise", Bell Syst. Tech. J. 24, 1945;
/// Cramér H. & Leadbetter M. R., Stationary and Related Stochastic Processes, Wiley 1967, §10.
pub fn step_scan(y: &[f64], noise: &NoiseSpectrum) -> Option<StepScan> {
    let n = y.len();
    let tau0 = noise.tau0;
    let w = step_window(n, noise);
    if n < 2 * w + 1 {
        return None;
    }
    let var_d = 2.0 * noise.avar(w as f64 * tau0);
    if var_d.is_nan() || var_d <= 0.0 {
        return None;
    }
    let prefix = FinitePrefix::new(y);
    let (index, size, inflate) = prefix.best_contrast(w)?;
    let wf = w as f64;
    let wt = wf * tau0;
    let lambda2 = ((4.0 * noise.rate_structure(wt) - noise.rate_structure(2.0 * wt)) / (wf * wf) / var_d).max(0.0);
    // Fewer finite samples next to a gap: a larger variance there.
    let var_d = var_d * inflate;
    // At each end, a window of W/2^k on the short side against W on the other, each contrast
    // against its own variance.
    let short: Vec<usize> = (1..=STEP_END_SPLITS).map(|k| w >> k).filter(|&a| a >= 2).collect();
    let ends = prefix
        .end_contrasts(w, short.iter().copied())
        .filter_map(|c| {
            let var = noise.contrast_variance(c.before as f64 * tau0, c.after as f64 * tau0) * c.inflate;
            (var > 0.0).then_some((c.at, c.size, var))
        })
        .max_by(|a, b| (a.1 * a.1 / a.2).total_cmp(&(b.1 * b.1 / b.2)));
    let (index, size, var_d) = match ends {
        Some(end) if end.1 * end.1 / end.2 > size * size / var_d => end,
        _ => (index, size, var_d),
    };
    let mut scan = StepScan {
        index,
        size,
        sigma: var_d.sqrt(),
        t2: size * size / var_d,
        p_value: 1.0,
        window: w,
        positions: (n - 2 * w + 1) as f64,
        lambda2,
        end_positions: 2.0 * short.len() as f64,
    };
    scan.p_value = scan.p_at(scan.t2);
    Some(scan)
}

/// A two-window contrast of [`FinitePrefix::contrast_between`]: D = `size` at sample `at`, with
/// `before` samples before it and `after` from it, its variance inflated by `inflate` for gaps.
struct Contrast {
    at: usize,
    before: usize,
    after: usize,
    size: f64,
    inflate: f64,
}

/// Prefix sums and counts of the finite samples of a series: window means that leave gaps out.
///
/// Why: a gap (NaN samples: dropped messages, a pause) read as zeros pulls a window's mean towards
/// 0, a false step as large as the level times the gap's share of the window (an accelerometer's
/// 9.8 m/s² with 500 missing samples in a window of 3000 gave `bias_step` on clean data).
struct FinitePrefix {
    sum: Vec<f64>,
    /// Finite samples before each index; `None` when every sample is finite (the count is then
    /// the index: a whole-run record without gaps needs no second series-long array).
    count: Option<Vec<usize>>,
}

impl FinitePrefix {
    fn new(y: &[f64]) -> FinitePrefix {
        let mut sum = Vec::with_capacity(y.len() + 1);
        let mut acc = 0.0;
        sum.push(0.0);
        for &v in y {
            if v.is_finite() {
                acc += v;
            }
            sum.push(acc);
        }
        let count = y.iter().any(|v| !v.is_finite()).then(|| {
            let mut finite = 0;
            std::iter::once(0)
                .chain(y.iter().map(|v| {
                    finite += usize::from(v.is_finite());
                    finite
                }))
                .collect()
        });
        FinitePrefix { sum, count }
    }

    /// Finite samples in y[a..b].
    fn finite(&self, a: usize, b: usize) -> usize {
        self.count.as_ref().map_or(b - a, |count| count[b] - count[a])
    }

    /// The two-window contrast at `i` with windows of `w` samples:
    /// D(i) = mean(y[i..i+w]) − mean(y[i−w..i]) over the finite samples, and the factor
    /// w / min(c₁, c₂) by which fewer samples inflate its variance (exact for white noise,
    /// conservative for coloured). `None` when a window is less than half finite.
    fn contrast(&self, i: usize, w: usize) -> Option<(f64, f64)> {
        self.contrast_between(i, w, w)
    }

    /// The largest contrast D²/inflate of [`FinitePrefix::contrast`] over i = w ..= n − w (the
    /// last of equals): (i, D, inflate).
    ///
    /// Why a loop of its own without gaps: each window then holds w finite samples, D is
    /// (S[i+w] − S[i])/w − (S[i] − S[i−w])/w and the inflation 1, the same operations as the
    /// general path's without its branches, over every sample of the record.
    fn best_contrast(&self, w: usize) -> Option<(usize, f64, f64)> {
        let n = self.sum.len() - 1;
        if self.count.is_some() {
            return (w..=n - w)
                .filter_map(|i| self.contrast(i, w).map(|(d, inflate)| (i, d, inflate)))
                .max_by(|a, b| (a.1 * a.1 / a.2).total_cmp(&(b.1 * b.1 / b.2)));
        }
        let (s, wf) = (&self.sum, w as f64);
        let mut best: Option<(usize, f64, f64)> = None;
        for i in w..=n - w {
            let d = (s[i + w] - s[i]) / wf - (s[i] - s[i - w]) / wf;
            if best.is_none_or(|(_, b, _)| (d * d).total_cmp(&(b * b)).is_ge()) {
                best = Some((i, d, 1.0));
            }
        }
        best
    }

    /// [`FinitePrefix::contrast`] with `before` samples before `i` and `after` from it: the
    /// factor is the larger of the two windows' length / finite count.
    fn contrast_between(&self, i: usize, before: usize, after: usize) -> Option<(f64, f64)> {
        let mean = |a: usize, b: usize| {
            let c = self.finite(a, b);
            (2 * c >= b - a && c > 0).then(|| ((self.sum[b] - self.sum[a]) / c as f64, c))
        };
        let (later, ca) = mean(i, i + after)?;
        let (earlier, cb) = mean(i - before, i)?;
        Some((later - earlier, (after as f64 / ca as f64).max(before as f64 / cb as f64)))
    }

    /// The contrasts within `w` of either end of the series: for each `a` of `short`, `a`
    /// samples against the `w` after them at the start, and `w` against the last `a` at the end.
    fn end_contrasts<'a>(
        &'a self,
        w: usize,
        short: impl Iterator<Item = usize> + 'a,
    ) -> impl Iterator<Item = Contrast> + 'a {
        let n = self.sum.len() - 1;
        short.flat_map(move |a| [(a, a, w), (n - a, w, a)]).filter_map(|(at, before, after)| {
            let (size, inflate) = self.contrast_between(at, before, after)?;
            Some(Contrast { at, before, after, size, inflate })
        })
    }
}

/// Two-sided p-value of a t statistic given as t² (the normal tail, ×`tests` for the best of
/// that many).
pub fn p_of_t2(t2: f64, tests: usize) -> f64 {
    (tests.max(1) as f64 * erfc((t2.max(0.0) / 2.0).sqrt())).min(1.0)
}

/// How many times the Gaussian likelihood ratio of [`find_burst`] over-counts its evidence when
/// the first differences of `series` have heavier tails than a Gaussian's (never below 1).
///
/// # Formula
/// ```text
/// factor = max(1, (κ − 1)/2),   κ = mean over blocks of m₄/m₂² · (n + 1)/(n − 1)
/// ```
/// with m₂, m₄ the central moments of the first differences within each block of
/// [`block_len`] samples (n of them). A block variance's own variance is (κ − 1)σ⁴/n, 2σ⁴/n for a
/// Gaussian: the ratio is the fourth-moment analogue of [`NoiseSpectrum::burst_dof_factor`].
/// Within blocks, so that a real burst (a change of variance between blocks) does not read as a
/// heavy tail; (n + 1)/(n − 1) undoes the small-sample bias of the ratio (3(n − 1)/(n + 1) for a
/// Gaussian).
///
/// Why: quantization that the other noise does not dither makes most differences zero and a few
/// one output step (κ ≈ 10 at 0.1 step of noise per sample); its block variances then scatter
/// several times more than a Gaussian's, and a ×1.07–1.24 "burst" passed the Gaussian threshold on
/// hidden quantization (tests/hidden_effects.rs, seeds 81 and 82).
///
/// κ is the larger of that and the record's own kurtosis of the differences where
/// [`white_fourth_cumulant`] found heavy tails (`fourth_cumulant` > 0: 3 + κ₄(d)/(E d²)²,
/// κ₄(d) = 2κ₄). Why both: a
/// block's kurtosis cannot exceed its n, and most one-second blocks hold no spike at all, so the
/// blocks' mean misses rare spikes (one sample in a thousand at ±15σ: κ of the differences ≈ 20),
/// and a cluster of them passed for a burst (tests/model_clean.rs,
/// `isolated_spikes_widen_the_intervals_and_make_no_suggestion`).
///
/// [`white_fourth_cumulant`]: crate::allan::edf::white_fourth_cumulant
pub fn tail_factor(series: &[f64], tau0: f64, fourth_cumulant: f64) -> f64 {
    let n = block_len(tau0);
    let (mut sum, mut blocks) = (0.0, 0usize);
    // One block of differences at a time (the record may hold millions); a last partial block is
    // left out.
    let mut block = Vec::with_capacity(n);
    let (mut squares, mut differences) = (0.0, 0usize);
    for d in series.windows(2).map(|w| w[1] - w[0]).filter(|d| d.is_finite()) {
        (squares, differences) = (squares + d * d, differences + 1);
        block.push(d);
        if block.len() < n {
            continue;
        }
        let mean = block.iter().sum::<f64>() / n as f64;
        let (m2, m4) = block.iter().fold((0.0, 0.0), |(m2, m4), d| {
            let c = (d - mean) * (d - mean);
            (m2 + c, m4 + c * c)
        });
        if m2 > 0.0 {
            sum += m4 * n as f64 / (m2 * m2);
            blocks += 1;
        }
        block.clear();
    }
    if blocks == 0 {
        return 1.0;
    }
    let within_blocks = sum / blocks as f64 * (n as f64 + 1.0) / (n as f64 - 1.0);
    let mean_square = squares / differences as f64;
    let of_record = match fourth_cumulant > 0.0 {
        true => 3.0 + 2.0 * fourth_cumulant / (mean_square * mean_square),
        false => 0.0,
    };
    ((within_blocks.max(of_record) - 1.0) / 2.0).max(1.0)
}

/// How many times the block variances of [`find_burst`] scatter more than independent Gaussian
/// differences would make them, measured on the record itself between neighbouring blocks
/// (never below 1): the measured counterpart of [`NoiseSpectrum::burst_dof_factor`] ×
/// [`tail_factor`] (1.5 for white Gaussian noise, whose neighbouring differences are correlated).
///
/// # Formula
/// ```text
/// vₖ = Σ_{block k} (y[i+1] − y[i])² / n,   factor = max(1, mean((vₖ₊₁ − vₖ)²/(2·v̄ₖ²)) / (2/n))
/// ```
/// with n the differences per block and v̄ₖ = (vₖ + vₖ₊₁)/2: were the differences independent and
/// Gaussian, a block's mean square would scatter by 2v²/n about its level v. Between neighbouring
/// blocks and relative to their level, so that a louder span adds two terms (its edges) and a slow
/// change of level nothing.
///
/// Why, beside [`tail_factor`]: that one reads the kurtosis of single differences, but a spike left
/// in a record moves two neighbouring differences at once (by +s and −s), which scatters a block's
/// variance twice as much as its kurtosis says. With spikes of 8σ one sample in 200 and a
/// threshold of 8σ_r in [`despiked`], a tenth of them stayed and gave false bursts on 13 and 20 of
/// 144 clean axes; with this factor 7 and 12 (docs/model.md, "Heavy tails").
pub fn block_dispersion_factor(series: &[f64], tau0: f64) -> f64 {
    let n = block_len(tau0);
    let variances: Vec<f64> = series
        .chunks_exact(n)
        .filter_map(|block| {
            let (sum, count) = block
                .windows(2)
                .map(|w| w[1] - w[0])
                .filter(|d| d.is_finite())
                .fold((0.0, 0usize), |(s, c), d| (s + d * d, c + 1));
            (count + 1 == n).then(|| sum / count as f64)
        })
        .collect();
    if variances.len() < 8 {
        return 1.0;
    }
    // Each pair relative to its own level, so that a louder span scatters as much as the rest.
    let pairs = variances.windows(2).filter(|w| w[0] + w[1] > 0.0);
    let (sum, count) = pairs.fold((0.0, 0usize), |(s, c), w| {
        let level = 0.5 * (w[0] + w[1]);
        (s + 0.5 * (w[1] - w[0]).powi(2) / (level * level), c + 1)
    });
    if count == 0 {
        return 1.0;
    }
    (sum / count as f64 / (2.0 / (n - 1) as f64)).max(1.0)
}

/// Samples per block for windowed statistics: about one second, at least 8 samples.
pub fn block_len(tau0: f64) -> usize {
    ((1.0 / tau0).round() as usize).max(8)
}

/// `series` as the searches on sample-to-sample differences read it: [`despiked`] where the
/// record is heavier-tailed than Gaussian (`fourth_cumulant` > 0, [`estimate`]), else itself.
pub fn without_spikes(series: &[f64], tau0: f64, fourth_cumulant: f64) -> std::borrow::Cow<'_, [f64]> {
    match fourth_cumulant > 0.0 {
        true => despiked(series, tau0),
        false => std::borrow::Cow::Borrowed(series),
    }
}

/// How far a sample must stand out from the median of the five around it, in robust σ of that
/// residual, to be taken for an isolated spike by [`despiked`].
///
/// Why 6: the residual from a median of five is heavier-tailed than a Gaussian (its σ_r from the
/// median absolute deviation is 0.73σ of the samples, its standard deviation 0.94σ), and σ_r is
/// measured on a few hundred samples, so it scatters. Over 3.6·10⁶ samples of white Gaussian noise
/// in groups of 256 (measured with numpy), 669 reached 6σ_r, 99 reached 7σ_r and 13 reached 8σ_r:
/// at 6σ_r one sample in 5 000 is replaced by its neighbours' median, which changes no statistic
/// measurably, and a spike of 4.4σ of the white noise is found. At 8σ_r (5.8σ) a tenth of the
/// spikes of 8σ one sample in 200 stayed, and the burst test named 13 and 20 of 144 clean axes
/// (docs/model.md, "Heavy tails"); at 6σ_r, 1 and 1, as before the search read past spikes.
pub const SPIKE_SIGMAS: f64 = 6.0;

/// Fewest samples over which [`despiked`] measures its robust scale: one block, or more where a
/// block is short (in groups of 100 samples the scale scatters by 12 %, and white noise reached
/// 6σ_r three times as often as in groups of 256).
const SPIKE_SCALE_SAMPLES: usize = 256;

/// `series` with its isolated spikes replaced by the median of their four neighbours; borrowed
/// when it has none.
///
/// # Formula
/// ```text
/// rᵢ = yᵢ − median(yᵢ₋₂ … yᵢ₊₂),   σ_r = median |r| / 0.6745 over groups of max(block, 256) samples
/// yᵢ ← median of its unflagged neighbours among yᵢ₋₂, yᵢ₋₁, yᵢ₊₁, yᵢ₊₂   where |rᵢ| > SPIKE_SIGMAS·σ_r
/// ```
/// (Hampel's identifier on a five-sample window). A median of five ignores up to two spikes in the
/// window, so two spikes side by side are both found and neither moves the other's neighbours' r.
/// σ_r is the local one, so that a louder span (a burst) keeps its samples.
///
/// Why: the statistics of sample-to-sample differences ([`find_burst`], [`tail_factor`]) are sums
/// of squares, and one spike of 30σ adds to its one-second block (two differences of 30σ, 1 800σ²)
/// as much as nine blocks of noise at 100 Hz (100 differences of 2σ² each). In
/// such a record (one sample in 2 000 at ±30σ; a real XSens MTi-G gyro reads an excess kurtosis
/// of 117) the burst search found spikes and its test, widened for them, missed every burst of the
/// stated-visibility test (0 of 20, docs/model.md "Heavy tails"). Used only where the record is
/// measurably heavier-tailed than Gaussian ([`without_spikes`]), so a Gaussian record's search is
/// unchanged, bit for bit.
///
/// # References
/// F. R. Hampel, "The influence curve and its role in robust estimation", JASA 69(346), 1974 (the
/// median absolute deviation as a scale, 1/0.6745 its Gaussian consistency factor); R. K. Pearson,
/// "Outliers in process modeling and identification", IEEE TCST 10(1), 2002 (the Hampel filter).
pub fn despiked(series: &[f64], tau0: f64) -> std::borrow::Cow<'_, [f64]> {
    let n = series.len();
    if n < 5 {
        return std::borrow::Cow::Borrowed(series);
    }
    let median = |v: &mut [f64]| {
        v.sort_unstable_by(f64::total_cmp);
        let h = v.len() / 2;
        if v.len() % 2 == 1 { v[h] } else { 0.5 * (v[h - 1] + v[h]) }
    };
    let residual = |i: usize| {
        let mut w = [0.0; 5];
        w.copy_from_slice(&series[i - 2..=i + 2]);
        let r = series[i] - median(&mut w);
        r.is_finite().then_some(r)
    };
    // Flagged samples, group by group: the group's residuals give its scale, then its spikes.
    let group = block_len(tau0).max(SPIKE_SCALE_SAMPLES);
    let mut residuals: Vec<(usize, f64)> = Vec::with_capacity(group);
    let mut magnitudes = Vec::with_capacity(group);
    let mut flagged = Vec::new();
    for start in (2..n - 2).step_by(group) {
        residuals.clear();
        residuals.extend((start..(start + group).min(n - 2)).filter_map(|i| residual(i).map(|r| (i, r))));
        magnitudes.clear();
        magnitudes.extend(residuals.iter().map(|(_, r)| r.abs()));
        if magnitudes.is_empty() {
            continue;
        }
        // A group of equal samples (a record on a coarse output lattice) has no spikes to tell.
        let scale = median(&mut magnitudes) / 0.6745;
        if scale > 0.0 {
            flagged.extend(residuals.iter().filter(|(_, r)| r.abs() > SPIKE_SIGMAS * scale).map(|&(i, _)| i));
        }
    }
    if flagged.is_empty() {
        return std::borrow::Cow::Borrowed(series);
    }
    let mut y = series.to_vec();
    for &i in &flagged {
        let mut around: Vec<f64> = [i - 2, i - 1, i + 1, i + 2]
            .into_iter()
            .filter(|j| flagged.binary_search(j).is_err())
            .map(|j| series[j])
            .filter(|v| v.is_finite())
            .collect();
        if !around.is_empty() {
            y[i] = median(&mut around);
        }
    }
    std::borrow::Cow::Owned(y)
}

/// The most likely single step in the mean: local two-window contrast, maximised.
///
/// Returns (first sample after the step, size, strength = contrast² / its robust typical value).
///
/// # Formula
/// ```text
/// D(i) = mean(y[i..i+W]) − mean(y[i−W..i]),   i* = argmax |D(i)|,   size = D(i*)
/// within W of an end: the window on the short side is a = i (or n − i), down to W/16,
///   and D(i)² is compared in units of (1/a + 1/W)/(2/W), its variance under white noise
/// ```
/// W = n/30 samples: long enough to average the white noise, short enough that a random walk
/// does not look like a step.
pub fn find_step(y: &[f64]) -> (usize, f64, f64) {
    let n = y.len();
    let w = (n / 30).max(2);
    if n < 2 * w + 1 {
        return (0, 0.0, 0.0);
    }
    let prefix = FinitePrefix::new(y);
    // D² in units of its no-gap variance: positions next to a gap count for less.
    let contrast = |i: usize| prefix.contrast(i, w).map(|(d, inflate)| (d, d * d / inflate));
    let (best_i, best_d, best_d2) = (w..=n - w)
        .filter_map(|i| contrast(i).map(|(d, d2)| (i, d, d2)))
        .max_by(|a, b| a.2.total_cmp(&b.2))
        .unwrap_or((0, 0.0, 0.0));
    // Within W of an end: a shorter window on that side (down to W/16), its D² in units of the
    // two-window variance under white noise, (1/a + 1/W)/(2/W) times the full one's.
    let shortest = (w >> STEP_END_SPLITS).max(1);
    let ends = prefix.end_contrasts(w, shortest..w).map(|c| {
        let a = c.before.min(c.after) as f64;
        let white = (1.0 / a + 1.0 / w as f64) * w as f64 / 2.0;
        (c.at, c.size, c.size * c.size / (c.inflate * white))
    });
    let (best_i, best_d, best_d2) =
        ends.fold((best_i, best_d, best_d2), |best, end| if end.2 > best.2 { end } else { best });
    // E[D²] = 2σ²_A(W·τ0) for stationary noise; estimated robustly from the median of D² on a
    // grid of positions (a step touches only 2W of them): median(χ²₁) = 0.4549.
    let mut d2: Vec<f64> = (w..=n - w).step_by((w / 4).max(1)).filter_map(|i| contrast(i).map(|c| c.1)).collect();
    d2.sort_by(f64::total_cmp);
    let typical = d2.get(d2.len() / 2).copied().unwrap_or(0.0) / 0.4549;
    let strength = if typical > 0.0 { best_d2 / typical } else { 0.0 };
    (best_i, best_d, strength)
}

/// A span where the white level is higher than elsewhere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Burst {
    /// First sample inside.
    pub start: usize,
    /// First sample after.
    pub end: usize,
    /// Ratio of white standard deviations inside / outside.
    pub factor: f64,
    /// Log-likelihood ratio against "no burst".
    pub strength: f64,
}

impl Burst {
    /// No burst: an empty span, factor 1, strength 0.
    pub const NONE: Burst = Burst { start: 0, end: 0, factor: 1.0, strength: 0.0 };
}

/// Finds the one span whose white-noise level differs most, by a Gaussian likelihood ratio on
/// per-block variances of first differences (slow effects cancel in the differences).
///
/// The search is exact and costs O(nb·h) instead of the O(nb²) of scoring every span: LLR is a
/// convex function of the span's point (n_in, V_in), and every span is a difference of two points
/// of the cumulative path Pₖ = (Σ_{j<k} n_j, Σ_{j<k} v_j). For a fixed start s, a convex function
/// of P_e − P_s takes its maximum over e > s at a vertex of the convex hull of {P_e : e > s}; the
/// lower and upper hulls of those suffixes are kept on two stacks while s walks backwards (Andrew's
/// monotone chain: each point pushed and popped once). h, the number of hull vertices, is that of
/// the convex minorant plus the concave majorant of a random walk: about 2·ln nb for noise, so the
/// search is O(nb log nb) on data (13 h of 1 s blocks: 1.1·10⁹ spans scored before, issue 11).
///
/// # Formula
/// ```text
/// vₖ = Σ_{block k} (y[i+1] − y[i])² / 2        (b samples per block)
/// LLR(s, e) = ½·[n·ln(V/n) − n_in·ln(V_in/n_in) − n_out·ln(V_out/n_out)]
/// ```
/// maximised over block spans [s, e), where V sums vₖ and n counts differences. n·ln(V/n) is the
/// perspective of ln, concave in (n, V), so LLR is convex wherever V_in, V_out > 0 (a span of
/// exactly constant samples, V_in = 0 with n_in > 0, is the one case the hull may miss). LLR ≥ 0
/// and is 0 for the whole record, so leaving that span out never hides a better one.
/// Only spans louder than the rest are scored (a burst is louder: `VariancePath::score`), and
/// their maximum is still at a hull vertex: on the louder side LLR grows with V_in at fixed n_in,
/// so a louder point lies below the upper hull's segment between two vertices, and on that
/// segment the convex LLR, zero where it crosses factor 1, peaks at a louder vertex.
///
/// # References
/// S. Boyd, L. Vandenberghe, Convex Optimization, Cambridge University Press, 2004, §3.2.6
/// (perspective). A. M. Andrew, "Another efficient algorithm for convex hulls in two dimensions",
/// Information Processing Letters 9(5), 1979. P. Groeneboom, "The concave majorant of Brownian
/// motion", Annals of Probability 11(4), 1983 (the logarithmic vertex count).
pub fn find_burst(y: &[f64], tau0: f64) -> Burst {
    let Some(path) = VariancePath::new(y, block_len(tau0)) else {
        return Burst::NONE;
    };
    let nb = path.blocks();
    let (pc, pv) = (&path.pc, &path.pv);
    // (b − a) × (c − a) on path points: > 0 when a → b → c turns left.
    let cross = |a: usize, b: usize, c: usize| {
        (pc[b] - pc[a]) * (pv[c] - pv[a]) - (pv[b] - pv[a]) * (pc[c] - pc[a])
    };
    // Stacks of path indices, the newest (leftmost) point on top. Collinear and repeated points
    // are dropped (a convex function on a segment peaks at an end), the lower index kept.
    let (mut lower, mut upper): (Vec<usize>, Vec<usize>) = (Vec::new(), Vec::new());
    let mut best = Burst::NONE;
    let mut best_span = (usize::MAX, usize::MAX);
    for s in (0..nb).rev() {
        let p = s + 1;
        while lower.len() >= 2 && cross(p, lower[lower.len() - 1], lower[lower.len() - 2]) <= 0.0 {
            lower.pop();
        }
        lower.push(p);
        while upper.len() >= 2 && cross(p, upper[upper.len() - 1], upper[upper.len() - 2]) >= 0.0 {
            upper.pop();
        }
        upper.push(p);
        for &e in lower.iter().chain(&upper) {
            let Some(burst) = path.score(s, e) else { continue };
            // Ties go to the earliest span, as a scan in (s, e) order would report.
            let tie = burst.strength == best.strength && (s, e) < best_span;
            if burst.strength > best.strength || (tie && burst.strength > 0.0) {
                best = burst;
                best_span = (s, e);
            }
        }
    }
    best
}

/// The cumulative path of per-block half squared first differences and their counts, the input
/// of [`find_burst`].
struct VariancePath {
    /// Samples per block.
    b: usize,
    /// Σ vⱼ for j < k, k = 0..=nb.
    pv: Vec<f64>,
    /// Σ nⱼ for j < k.
    pc: Vec<f64>,
    /// n·ln(V/n) of the whole record.
    total: f64,
}

impl VariancePath {
    /// The path of `y` in blocks of `b` samples; `None` under 4 blocks or without spread.
    fn new(y: &[f64], b: usize) -> Option<Self> {
        let nb = y.len() / b;
        if nb < 4 {
            return None;
        }
        let (mut pv, mut pc) = (Vec::with_capacity(nb + 1), Vec::with_capacity(nb + 1));
        let (mut sv, mut sc) = (0.0, 0.0);
        pv.push(sv);
        pc.push(sc);
        for k in 0..nb {
            let blk = &y[k * b..((k + 1) * b + 1).min(y.len())];
            let (s, n) = blk
                .windows(2)
                .filter(|p| p[0].is_finite() && p[1].is_finite())
                .fold((0.0, 0usize), |(s, n), p| (s + 0.5 * (p[1] - p[0]).powi(2), n + 1));
            sv += s;
            sc += n as f64;
            pv.push(sv);
            pc.push(sc);
        }
        if sv <= 0.0 || sc <= 0.0 {
            return None;
        }
        Some(VariancePath { b, pv, pc, total: ll(sv, sc) })
    }

    fn blocks(&self) -> usize {
        self.pv.len() - 1
    }

    /// The span of blocks [s, e) as a burst; `None` for the whole record, an empty side, or a
    /// span quieter than the rest.
    ///
    /// Only louder spans: a burst is louder than the record around it (`noise_burst`'s factor is
    /// ≥ 1, and a quiet span is expressed as a burst over the rest), so a quiet span, scored, was
    /// found and its factor clamped to 1 — an estimate of nothing. A noise level that changes
    /// once, for good, is the louder side as a burst that runs to the record's end (issue 10:
    /// the ADIS16405's accel_y is 15 % louder after its first half hour, and the search returned
    /// the quiet 13–2155 s). The hull search stays exact (see [`find_burst`]).
    fn score(&self, s: usize, e: usize) -> Option<Burst> {
        let nb = self.blocks();
        let (vt, ct) = (self.pv[nb], self.pc[nb]);
        let (vi, ci) = (self.pv[e] - self.pv[s], self.pc[e] - self.pc[s]);
        let (vo, co) = (vt - vi, ct - ci);
        if e - s == nb || ci <= 0.0 || co <= 0.0 || vi / ci < vo / co {
            return None;
        }
        Some(Burst {
            start: s * self.b,
            end: e * self.b,
            factor: ((vi / ci) / (vo / co)).sqrt(),
            strength: 0.5 * (self.total - ll(vi, ci) - ll(vo, co)),
        })
    }
}

/// n·ln(V/n), 0 for an empty or constant part.
fn ll(v: f64, n: f64) -> f64 {
    if n > 0.0 && v > 0.0 {
        n * (v / n).ln()
    } else {
        0.0
    }
}

/// Scales the fast part of `span` down by `factor` around a 30 s moving mean (the slow part).
pub(crate) fn shrink_white(span: &mut [f64], factor: f64, block: usize) {
    if factor <= 1.0 || span.is_empty() {
        return;
    }
    let half = (15 * block).max(1);
    let mut prefix = Vec::with_capacity(span.len() + 1);
    let mut acc = 0.0;
    prefix.push(0.0);
    for &v in span.iter() {
        acc += if v.is_finite() { v } else { 0.0 };
        prefix.push(acc);
    }
    let n = span.len();
    for (i, y) in span.iter_mut().enumerate() {
        let (lo, hi) = (i.saturating_sub(half), (i + half + 1).min(n));
        let mean = (prefix[hi] - prefix[lo]) / (hi - lo) as f64;
        *y = mean + (*y - mean) / factor;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
    }

    #[test]
    fn tail_factor_is_one_for_gaussian_noise_and_a_burst_and_large_for_undithered_steps() {
        let white = noise(360_000, 5);
        let f = tail_factor(&white, 0.01, 0.0);
        assert!((1.0..1.03).contains(&f), "white: {f}");
        // A ×3 burst over a sixth of the record: the variance changes between blocks, not its tails.
        let burst: Vec<f64> = white.iter().enumerate().map(|(i, v)| if i < 60_000 { 3.0 * v } else { *v }).collect();
        let f = tail_factor(&burst, 0.01, 0.0);
        assert!((1.0..1.03).contains(&f), "burst: {f}");
        // The rate of an angle rounded to steps of 10 noise σ per sample: mostly 0, now and then one step.
        let mut angle = 0.0;
        let mut last = 0.0;
        let steps: Vec<f64> = white
            .iter()
            .map(|v| {
                angle += v;
                let q = (angle / 10.0f64).round() * 10.0;
                let rate = q - last;
                last = q;
                rate
            })
            .collect();
        let f = tail_factor(&steps, 0.01, 0.0);
        assert!(f > 3.0, "undithered: {f}");
    }

    #[test]
    fn block_dispersion_is_the_gaussian_one_for_noise_and_a_burst_and_larger_with_spikes() {
        let white = noise(360_000, 7);
        // White noise: neighbouring differences correlate at −½, 1 + 2·(½)² = 1.5 (burst_dof_factor).
        let f = block_dispersion_factor(&white, 0.01);
        assert!((1.4..1.6).contains(&f), "white: {f}");
        // A ×3 burst over a sixth of the record: two edges among 3 600 blocks.
        let burst: Vec<f64> = white.iter().enumerate().map(|(i, v)| if i < 60_000 { 3.0 * v } else { *v }).collect();
        let f = block_dispersion_factor(&burst, 0.01);
        assert!((1.4..1.7).contains(&f), "burst: {f}");
        // Spikes of 6σ in one block in ten, mid-block: each moves two differences of that block
        // (measured with numpy on another draw: 1.46 → 1.86).
        let spiky: Vec<f64> = white.iter().enumerate().map(|(i, v)| if i % 1_000 == 550 { v + 6.0 } else { *v }).collect();
        let f = block_dispersion_factor(&spiky, 0.01);
        assert!(f > 1.8, "spiky: {f}");
    }

    #[test]
    fn despiking_replaces_the_spikes_and_nothing_else() {
        let white = noise(360_000, 6);
        // Gaussian noise: about 2·10⁻⁴ of the samples reach 6σ_r (SPIKE_SIGMAS): 67 expected.
        let changed = |y: &[f64], x: &[f64]| y.iter().zip(x).filter(|(a, b)| a != b).count();
        let gaussian = changed(&despiked(&white, 0.01), &white);
        assert!(gaussian <= 110, "Gaussian: {gaussian}");
        // Spikes of ±12 to ±46 local σ, one in 500, some side by side, inside and outside ×3
        // bursts (not within a scale group of a burst's edge, where the scale is a mix of both).
        let level = |i: usize| if (50_000..300_000).contains(&i) && i % 10_000 < 3_000 { 3.0 } else { 1.0 };
        let louder: Vec<f64> = white.iter().enumerate().map(|(i, v)| level(i) * v).collect();
        let mut spiky = louder.clone();
        let mut at = Vec::new();
        for k in 0..700 {
            let i = 1_000 + 500 * k + (k * 37) % 400;
            if level(i - 300) != level(i + 300) {
                continue;
            }
            let size = level(i) * if k % 2 == 0 { 12.0 + (k % 35) as f64 } else { -40.0 };
            spiky[i] += size;
            at.push(i);
            if k % 7 == 0 {
                spiky[i + 1] -= size;
                at.push(i + 1);
            }
        }
        let fixed = despiked(&spiky, 0.01);
        let missed: Vec<usize> = at.iter().copied().filter(|&i| (fixed[i] - louder[i]).abs() > 5.0 * level(i)).collect();
        assert!(missed.is_empty(), "spikes left: {missed:?}");
        // Outside the spikes, what changed is Gaussian's share, not the louder spans' samples: but
        // for some in the scale groups across the 50 edges of its 25 spans, whose scale mixes both
        // levels (measured: 167 samples there, 64 elsewhere, as in Gaussian noise alone: 74).
        let edge = |i: usize| level(i.saturating_sub(300)) != level(i + 300);
        let others: Vec<usize> = (0..spiky.len()).filter(|i| !at.contains(i) && fixed[*i] != spiky[*i]).collect();
        let (at_edges, elsewhere): (Vec<usize>, Vec<usize>) = others.iter().partition(|&&i| edge(i));
        assert!(elsewhere.len() <= 110 && at_edges.len() <= 300, "changed: {elsewhere:?} and {} at edges", at_edges.len());
        // A record on a lattice coarser than its noise has nothing to tell apart: left as it is.
        let lattice: Vec<f64> = white.iter().map(|v| (v / 10.0).round()).collect();
        assert!(matches!(despiked(&lattice, 0.01), std::borrow::Cow::Borrowed(_)));
    }

    #[test]
    fn fast_len_is_smooth_and_close() {
        assert_eq!(fast_len(63), 63);
        assert_eq!(fast_len(1 << 20), 1 << 20);
        // 1 572 863 = 3·524 287 (a Mersenne prime): the arbitrary length the 405 MB came from.
        let n = 1_572_863;
        let m = fast_len(n);
        assert!(m <= n && (n - m) as f64 / n as f64 <= 0.003, "{m}");
        assert!(m.is_multiple_of(2) && is_fast(m / 2));
        assert!(!is_fast(524_287) && is_fast(1 << 20) && !is_fast(17 * 64));
        assert!((m / 2 + 1..=n / 2).all(|k| !is_fast(k)));
        for k in 64..2000 {
            assert!(fast_len(k) as f64 >= 0.9 * k as f64, "{k}");
        }
        for k in (20_000..200_000).step_by(97) {
            assert!(fast_len(k) as f64 >= 0.99 * k as f64, "{k}");
        }
    }

    #[test]
    fn a_fast_length_is_transformed_without_scratch() {
        // The lengths rustfft leaves to Bluestein's algorithm (see is_fast) are not fast; every
        // fast length with 13² in it up to twice the record's cap of 2²⁰ samples transforms with no
        // scratch buffer (the others measured so, see is_fast).
        for m in [169, 4 * 169, 13usize.pow(4), 2 * 13usize.pow(5), 3 * 13usize.pow(5)] {
            assert!(!is_fast(m), "{m}");
        }
        assert!(is_fast(5 * 169) && is_fast(13 * 13 * 13 * 6) && is_fast(26) && is_fast(52));
        for m in (1..=(1 << 20) / 169).map(|j| j * 169).filter(|&m| is_fast(m)) {
            let plan = RealFftPlanner::<f64>::new().plan_fft_forward(2 * m);
            assert_eq!(plan.get_scratch_len(), 0, "length 2·{m}");
        }
    }

    #[test]
    fn a_regression_reads_the_same_tail_as_its_series() {
        // 1001 samples: 1000 differences = 2³·5³ are kept whole; 1010 → 1009 (prime) is cut to 1008.
        let spectrum =
            NoiseSpectrum::from_curves(0.01, &[1.0], [(NoiseClass::WhiteFm, &[1e-6][..])]);
        for n in [1001, 1010] {
            let y = noise(n, 7);
            let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.05).sin()).collect();
            let w = Whitened::new(&y, &spectrum).unwrap();
            let skip = n - 1 - fast_len(n - 1);
            let tail = Whitened::new(&y[skip..], &spectrum).unwrap();
            assert_eq!(w.regress(&x), tail.regress(&x[skip..]));
            assert!(w.regress(&x[1..]).is_none());
        }
    }

    #[test]
    fn step_is_located_and_sized() {
        let mut y = noise(60_000, 1);
        y.iter_mut().skip(21_000).for_each(|v| *v += 0.3);
        let (i, size, strength) = find_step(&y);
        assert!((i as i64 - 21_000).abs() < 300, "{i}");
        // D's white-noise sd is √(2/W) = 0.032 with W = 2000.
        assert!((size - 0.3).abs() < 4.0 * (2.0f64 / 2000.0).sqrt(), "{size}");
        assert!(strength > 50.0);
    }

    #[test]
    fn burst_is_located_and_sized() {
        let mut y = noise(100 * 1200, 2);
        let extra = noise(100 * 1200, 3);
        for i in 30_000..50_000 {
            y[i] += extra[i] * (9.0f64 - 1.0).sqrt();
        }
        let b = find_burst(&y, 0.01);
        assert!((b.start as i64 - 30_000).abs() <= 100 && (b.end as i64 - 50_000).abs() <= 100, "{b:?}");
        assert!((b.factor - 3.0).abs() < 0.1, "{b:?}");
    }

    /// Issue 10: a noise level that rises for good is the louder side, a burst up to the record's
    /// end (the search returned the quiet first part, and its factor was clamped to 1).
    #[test]
    fn a_louder_second_half_is_a_burst_to_the_end() {
        let mut y = noise(100 * 1200, 5);
        let n = y.len();
        y[n / 3..].iter_mut().for_each(|v| *v *= 1.15);
        let b = find_burst(&y, 0.01);
        // The end within ten 1 s blocks of the record's: the last blocks are as likely quiet as loud.
        assert!((b.start as i64 - (n / 3) as i64).abs() <= 300 && b.end + 1000 >= n, "{b:?}");
        assert!((b.factor - 1.15).abs() < 0.02, "{b:?}");
    }

    /// White rate noise plus a random walk (K²τ/3 = N²/τ at τ = 5 s), as a fitted model would give.
    fn coloured(n: usize, seed: u64, tau0: f64) -> (Vec<f64>, NoiseSpectrum) {
        wandering(n, seed, tau0, 3.5e-4)
    }

    /// White rate noise (1e-3 /√Hz) and a random walk of `k` per √s.
    fn wandering(n: usize, seed: u64, tau0: f64, k: f64) -> (Vec<f64>, NoiseSpectrum) {
        let nw = 1e-3;
        let w = noise(n, seed);
        let e = noise(n, seed + 1000);
        let mut walk = 0.0;
        let y = w
            .iter()
            .zip(&e)
            .map(|(a, b)| {
                walk += k * tau0.sqrt() * b;
                nw / tau0.sqrt() * a + walk
            })
            .collect();
        let taus = [1.0];
        let spectrum = NoiseSpectrum::from_curves(
            tau0,
            &taus,
            [(NoiseClass::WhiteFm, &[nw * nw][..]), (NoiseClass::RandomWalkFm, &[k * k / 3.0][..])],
        );
        (y, spectrum)
    }

    #[test]
    fn regression_on_a_slow_driver_is_calibrated_under_a_random_walk() {
        // A warm-up: the spurious regression a white-noise test falls for. Under the fitted
        // coloured noise t² must be χ²₁: mean 1 (sd of the mean of 200: 0.1), 1 % above 6.63.
        let (tau0, n) = (0.01, 30_000);
        let x: Vec<f64> = (0..n).map(|i| 8.0 * (1.0 - (-(i as f64) * tau0 / 100.0).exp())).collect();
        let t2: Vec<f64> = (0..200u64)
            .map(|s| {
                let (y, spectrum) = coloured(n, 10 + s, tau0);
                Whitened::new(&y, &spectrum).unwrap().regress(&x).unwrap().t2
            })
            .collect();
        let mean = t2.iter().sum::<f64>() / t2.len() as f64;
        let above = t2.iter().filter(|&&v| v > 6.63).count();
        assert!((0.7..=1.35).contains(&mean), "mean t² {mean}");
        assert!(above <= 8, "{above} of 200 above the 1 % point");
        // The OLS t² of the same data: the spurious regression.
        let (y, _) = coloured(n, 10, tau0);
        assert!(regress(&y, &x).2 > 50.0, "{}", regress(&y, &x).2);
    }

    #[test]
    fn block_regression_on_time_is_the_trend_and_recovers_a_driver() {
        let (tau0, n) = (0.01, 60_000);
        let (y, spectrum) = coloured(n, 5, tau0);
        let times: Vec<f64> = (0..n).map(|i| i as f64 * tau0).collect();
        let (on_time, line) =
            (block_regression(&y, Some(&times), &spectrum).unwrap(), trend(&y, &spectrum).unwrap());
        assert!((on_time.coefficient - line.coefficient).abs() <= 1e-9 * line.sigma, "{on_time:?} {line:?}");
        assert!((on_time.sigma / line.sigma - 1.0).abs() < 1e-9);
        // A warm-up driver, 5σ strong: its coefficient comes back within 3σ.
        let x: Vec<f64> = (0..n).map(|i| 3.0 * (1.0 - (-(i as f64) * tau0 / 200.0).exp())).collect();
        let sigma = block_regression(&y, Some(&x), &spectrum).unwrap().sigma;
        let c = 5.0 * sigma;
        let driven: Vec<f64> = y.iter().zip(&x).map(|(y, x)| y + c * x).collect();
        let r = block_regression(&driven, Some(&x), &spectrum).unwrap();
        assert!((r.coefficient - c).abs() < 3.0 * r.sigma && r.t2 > 4.0, "{r:?} for {c}");
        assert!(block_regression(&y, Some(&x[1..]), &spectrum).is_none());
    }

    #[test]
    fn a_slow_line_stands_out_of_its_bins_and_the_noise_alone_does_not() {
        // Under the noise a bin's ratio is a unit exponential: the largest of the ≤ 5 bins read
        // averages at most H₅ = 2.28 (fewer, correlated by the taper: less), and the Bonferroni p
        // over the record's bins is near 1.
        let (tau0, n) = (0.01, 60_000);
        let record_s = n as f64 * tau0;
        let f = 3.0 / record_s; // three periods
        let quiet: Vec<f64> = (0..100u64)
            .map(|s| {
                let (y, spectrum) = coloured(n, 100 + s, tau0);
                Whitened::new(&y, &spectrum).unwrap().line_power(f, &[]).unwrap().statistic
            })
            .collect();
        let mean = quiet.iter().sum::<f64>() / quiet.len() as f64;
        assert!((0.8..=2.6).contains(&mean), "mean statistic {mean}");
        let (y, spectrum) = coloured(n, 7, tau0);
        let w = Whitened::new(&y, &spectrum).unwrap();
        let p = w.line_power(f, &[]).unwrap();
        assert!(p.p_at(p.statistic) > 0.5, "{p:?}");
        // A line of 3 periods, 15 times the 10 s means' noise (mostly the random walk's): a bump
        // the Allan variance sees at τ ≈ 70 s only, with EDF of a few; its strongest bin, read
        // 5 % off the line, holds 89 times the noise's power (statistic 88.9, p < 1e-33).
        let a = 15.0 * spectrum.avar(10.0).sqrt();
        let lined: Vec<f64> =
            y.iter().enumerate().map(|(i, v)| v + a * (2.0 * std::f64::consts::PI * f * i as f64 * tau0).sin()).collect();
        let l = Whitened::new(&lined, &spectrum).unwrap();
        let p = l.line_power(f * 1.05, &[]).unwrap();
        assert!(p.p_at(p.statistic) < 1e-20, "{p:?}");
        // A line the model already holds is not read again.
        assert!(l.line_power(f * 1.05, &[f]).is_none());
    }

    #[test]
    fn regression_recovers_a_coefficient_within_its_sigma() {
        let (tau0, n) = (0.01, 30_000);
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * tau0 * 0.3).sin()).collect();
        let (mut y, spectrum) = coloured(n, 3, tau0);
        y.iter_mut().zip(&x).for_each(|(a, b)| *a += 2e-3 * b);
        let r = Whitened::new(&y, &spectrum).unwrap().regress(&x).unwrap();
        assert!((r.coefficient - 2e-3).abs() < 4.0 * r.sigma, "{r:?}");
        assert!(r.t2 > 100.0, "{r:?}");
    }

    #[test]
    fn the_gap_free_contrast_scan_is_the_general_one() {
        // Without gaps the scan's own loop must pick the contrast the general path picks (the
        // last of equal maxima), bit for bit; with a gap the general path runs.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut y: Vec<f64> = (0..5000)
            .map(|i| {
                let v: f64 = StandardNormal.sample(&mut rng);
                v + if i > 3100 { 1.5 } else { 0.0 }
            })
            .collect();
        let general = |p: &FinitePrefix, w: usize| {
            let n = p.sum.len() - 1;
            (w..=n - w)
                .filter_map(|i| p.contrast(i, w).map(|(d, inflate)| (i, d, inflate)))
                .max_by(|a, b| (a.1 * a.1 / a.2).total_cmp(&(b.1 * b.1 / b.2)))
        };
        for w in [2, 3, 50, 700] {
            let prefix = FinitePrefix::new(&y);
            let (got, want) = (prefix.best_contrast(w).unwrap(), general(&prefix, w).unwrap());
            assert_eq!((got.0, got.1.to_bits(), got.2.to_bits()), (want.0, want.1.to_bits(), want.2.to_bits()), "w = {w}");
        }
        assert_eq!(FinitePrefix::new(&y).best_contrast(50).unwrap().0 / 100, 31);
        // A square wave: equal maxima at every edge, the last one is taken.
        let square: Vec<f64> = (0..60).map(|i| ((i / 3) % 2) as f64).collect();
        let prefix = FinitePrefix::new(&square);
        let (got, want) = (prefix.best_contrast(3).unwrap(), general(&prefix, 3).unwrap());
        assert_eq!((got.0, got.1.to_bits()), (want.0, want.1.to_bits()));
        assert_eq!(got.0, 57);
        y[2000] = f64::NAN;
        let prefix = FinitePrefix::new(&y);
        assert_eq!(prefix.best_contrast(50), general(&prefix, 50));
    }

    #[test]
    fn step_scan_finds_a_step_and_stays_quiet_without_one() {
        let (tau0, n) = (0.01, 60_000);
        let (mut y, spectrum) = coloured(n, 5, tau0);
        let quiet = step_scan(&y, &spectrum).unwrap();
        assert!(quiet.p_value > 0.01, "{quiet:?}");
        let size = 8.0 * quiet.sigma;
        y.iter_mut().skip(25_000).for_each(|v| *v += size);
        let s = step_scan(&y, &spectrum).unwrap();
        assert!(s.p_value < 1e-6 && (s.index as i64 - 25_000).abs() < s.window as i64 / 2, "{s:?}");
        assert!((s.size - size).abs() < 2.0 * s.sigma, "{s:?}");
    }

    #[test]
    fn a_step_size_by_gls_is_calibrated_and_closer_than_the_contrast() {
        // White noise and a random walk, a step of 8 σ of the scan's test at 40 % of the record,
        // 40 seeds: the GLS size's z must be standard normal (mean z² 1; sd of the mean of 40
        // χ²₁ values 0.22), and its squared error below the scan's contrast's.
        let (tau0, n, at) = (0.01, 60_000, 24_000);
        let (mut z2, mut gls_err, mut contrast_err) = (0.0, 0.0, 0.0);
        let seeds = 40;
        for seed in 0..seeds {
            let (mut y, spectrum) = coloured(n, 100 + seed, tau0);
            let size = 8.0 * step_scan(&y, &spectrum).unwrap().sigma;
            y.iter_mut().skip(at).for_each(|v| *v += size);
            let (_, contrast, _) = find_step(&y);
            let g = step_size(&y, at, &spectrum).unwrap();
            z2 += ((g.coefficient - size) / g.sigma).powi(2) / seeds as f64;
            gls_err += ((g.coefficient - size) / size).powi(2);
            contrast_err += ((contrast - size) / size).powi(2);
        }
        assert!((0.5..1.7).contains(&z2), "mean z² {z2}");
        assert!(gls_err < 0.7 * contrast_err, "GLS {gls_err}, contrast {contrast_err}");
    }

    #[test]
    fn a_step_near_either_end_is_found_with_a_shorter_window_there() {
        // The scan's two full windows cannot straddle a step within W of an end; the shorter
        // windows at the ends can (W/2 … W/16), each against its own variance.
        let (tau0, n) = (0.01, 60_000);
        let (clean, spectrum) = coloured(n, 5, tau0);
        let quiet = step_scan(&clean, &spectrum).unwrap();
        assert!(quiet.p_value > 0.01, "{quiet:?}");
        let w = quiet.window;
        for at in [w / 5, n - w / 5] {
            let mut y = clean.clone();
            let size = 12.0 * quiet.sigma;
            y.iter_mut().skip(at).for_each(|v| *v += size);
            let s = step_scan(&y, &spectrum).unwrap();
            assert!(s.p_value < 1e-4 && s.index.abs_diff(at) <= w / 8, "step at {at} (W {w}): {s:?}");
            let (i, d, _) = find_step(&y);
            assert!(i.abs_diff(at) <= w / 8 && (d / size - 1.0).abs() < 0.5, "step at {at}: found {i}, {d:e}");
        }
    }

    #[test]
    fn a_contrast_of_two_equal_windows_has_twice_the_allan_variance() {
        // contrast_variance(W, W) = 2σ²_A(W) for each class; unequal windows of white FM give
        // a·(1/A + 1/B), the variance of a difference of two independent means.
        for class in [NoiseClass::WhitePm, NoiseClass::WhiteFm, NoiseClass::FlickerFm, NoiseClass::RandomWalkFm] {
            let one = NoiseSpectrum { tau0: 0.01, parts: vec![(class, 2.0)] };
            for w in [0.05, 3.0, 70.0] {
                let (c, a) = (one.contrast_variance(w, w), 2.0 * one.avar(w));
                assert!((c / a - 1.0).abs() < 1e-12, "{class:?} at {w} s: {c} vs {a}");
            }
        }
        let white = NoiseSpectrum { tau0: 0.01, parts: vec![(NoiseClass::WhiteFm, 2.0)] };
        assert!((white.contrast_variance(0.5, 8.0) - 2.0 * (2.0 + 0.125)).abs() < 1e-12);
    }

    /// A gap (NaN run) in a series far from zero is no step: the window means leave it out. Read
    /// as zeros (before), the same series gave a step of about level × gap / W with p ≈ 0.
    #[test]
    fn samples_missing_on_every_axis_do_not_correlate_two_independent_axes() {
        // Regression (the 24 h soak recording of benches/node_soak.rs, whose faults put ±1e300 on
        // all six axes of 10 messages an hour): read as the series' mean, each missing sample of
        // a wandering axis became a jump to the mean and back, at the same samples on the gyro and
        // on the accelerometer, and the gyro's GLS regression on the accelerometer found a
        // g-sensitivity (all three gyro axes at 24 h). Held at the last finite value, a missing
        // sample adds nothing; the increment across it stays in the next difference.
        let (tau0, n) = (0.01, 60_000);
        let t2 = |hole: bool, seed: u64| {
            // Random walks that wander some 25 white-noise σ from their means over the record.
            let (mut y, spectrum) = wandering(n, seed, tau0, 1e-2);
            let (mut x, _) = wandering(n, seed + 500, tau0, 1e-2);
            if hole {
                for at in (1_000..n).step_by(2_000) {
                    for v in [&mut y, &mut x] {
                        v[at..at + 10].iter_mut().for_each(|v| *v = f64::NAN);
                    }
                }
            }
            Whitened::new(&y, &spectrum).unwrap().regress(&x).unwrap().t2
        };
        for seed in [3, 4, 5] {
            let (whole, holed) = (t2(false, seed), t2(true, seed));
            // χ²₁ under the null: 10.8 is its 0.1 % point (TIME_ALPHA).
            assert!(holed < 10.8, "seed {seed}: t² {holed} with holes, {whole} without");
        }
    }

    #[test]
    fn a_gap_in_a_series_far_from_zero_is_no_step() {
        let (tau0, n) = (0.01, 60_000);
        let (mut y, spectrum) = coloured(n, 5, tau0);
        let quiet = step_scan(&y, &spectrum).unwrap();
        y.iter_mut().for_each(|v| *v += 9.8);
        y[30_000..30_700].iter_mut().for_each(|v| *v = f64::NAN);
        let gapped = step_scan(&y, &spectrum).unwrap();
        assert!(gapped.p_value > 0.01, "{gapped:?}");
        assert!(gapped.t2 < 2.0 * quiet.t2.max(9.0), "{gapped:?} vs {quiet:?}");
        let (_, size, _) = find_step(&y);
        assert!(size.abs() < 5.0 * quiet.sigma, "find_step size {size} vs σ {}", quiet.sigma);
    }

    /// The definition: every span of blocks scored, the first maximum kept.
    fn burst_by_all_spans(y: &[f64], tau0: f64) -> Burst {
        let Some(path) = VariancePath::new(y, block_len(tau0)) else {
            return Burst::NONE;
        };
        let nb = path.blocks();
        let mut best = Burst::NONE;
        for s in 0..nb {
            for e in s + 1..=nb {
                match path.score(s, e) {
                    Some(b) if b.strength > best.strength => best = b,
                    _ => {}
                }
            }
        }
        best
    }

    #[test]
    fn hull_search_equals_the_search_over_every_span() {
        // Seeded records of 2–20 min at 100 Hz: plain noise, bursts and quiet spans of every
        // length and place, a noise level ramping over the record, NaN runs, a leading gap.
        for seed in 0..40u64 {
            let n = 100 * (120 + 60 * (seed as usize % 19));
            let mut y = noise(n, 100 + seed);
            let extra = noise(n, 200 + seed);
            let (a, len) = ((seed as usize * 7919) % n, 100 * (1 + (seed as usize * 31) % 300));
            let factor = [1.0, 3.0, 0.5, 1.3, 1.1][seed as usize % 5];
            for i in a..(a + len).min(n) {
                y[i] = y[i] * factor + 0.1 * extra[i];
            }
            if seed % 4 == 1 {
                y.iter_mut().enumerate().for_each(|(i, v)| *v *= 1.0 + i as f64 / n as f64);
            }
            if seed % 6 == 2 {
                y[..350].iter_mut().for_each(|v| *v = f64::NAN);
                y[n / 2..n / 2 + 700].iter_mut().for_each(|v| *v = f64::NAN);
            }
            let (fast, slow) = (find_burst(&y, 0.01), burst_by_all_spans(&y, 0.01));
            assert_eq!(fast, slow, "seed {seed}");
        }
    }

    /// The order the removed `ORDER` list of ids gave: temperature, g_sensitivity, bias_step,
    /// noise_burst, then the rest (ramp, and any kind without an estimator) in the order given.
    #[test]
    fn estimation_order_is_regressions_then_step_then_burst_then_the_rest() {
        use crate::model::effects::{find, Domain, REGISTRY};
        let ids = |kinds: Vec<&'static dyn EffectKind>| kinds.iter().map(|k| k.id()).collect::<Vec<_>>();
        let mut kinds: Vec<_> = REGISTRY.iter().copied().filter(|k| k.domain() == Domain::TimeDomain).collect();
        let order = ["temperature", "g_sensitivity", "bias_step", "noise_burst", "ramp"];
        assert_eq!(ids(in_estimation_order(&kinds)), order);
        kinds.reverse();
        assert_eq!(ids(in_estimation_order(&kinds)), order);
        let white = find("white").unwrap();
        kinds.insert(0, white);
        assert_eq!(ids(in_estimation_order(&kinds)), [&order[..4], &["white", "ramp"]].concat());
    }

    #[test]
    fn regression_recovers_slope_with_honest_error() {
        let x: Vec<f64> = (0..5000).map(|i| (i as f64 * 0.01).sin()).collect();
        let e = noise(5000, 4);
        let y: Vec<f64> = x.iter().zip(&e).map(|(a, b)| 2.0 * a + b).collect();
        let (c, se, _) = regress(&y, &x);
        assert!((c - 2.0).abs() < 4.0 * se, "{c} ± {se}");
        assert!(se > 0.01 && se < 0.05);
    }
}

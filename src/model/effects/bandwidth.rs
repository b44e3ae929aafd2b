//! `bandwidth`: white rate noise seen through the sensor's own low-pass filter.

use super::{
    check_params, exponential, params_of, Domain, Effect, EffectKind, Evidence, Explanation,
    Extended, Extra, KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage,
};
use rand::RngCore;
use std::f64::consts::PI;

static SCHEMA: &[ParamSpec] = &[
    ParamSpec {
        name: "n",
        unit: "rad/s/sqrt(Hz)",
        bounds: (0.0, 10.0),
        doc: "white rate noise density N before the filter (angle random walk)",
    },
    ParamSpec {
        name: "cutoff_hz",
        unit: "Hz",
        bounds: (1e-3, 1e6),
        doc: "−3 dB frequency f_c of the first-order low-pass",
    },
];

/// The effect id (**contract** name) of this file's effect: `bandwidth`.
pub const ID: &str = "bandwidth";

static INFO: KindInfo = KindInfo {
    id: ID,
    alias: None,
    schema: SCHEMA,
    domain: Domain::Spectral,
    evidence: Evidence::None,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(Bandwidth::new(v[0], v[1])?)),
};

/// What the registry entry of [`Bandwidth`] adds to its [`KindInfo`]: the cut-off's search range.
pub(super) struct BandwidthExtra;

/// The registry entry of [`Bandwidth`].
pub(super) static KIND: Extended<BandwidthExtra> = Extended { info: &INFO, extra: BandwidthExtra };

impl Extra for BandwidthExtra {
    /// A low-pass shows in the Allan variance of samples at τ0 well above the Nyquist frequency:
    /// its deficit at τ0 is about 3/(4π·f_c·τ0) of N²/τ0 (7 % for f_c = 2/τ0), so the cut-off is
    /// searched up to 2/τmin, not capped at Nyquist like a sinusoid's frequency. Down to a time
    /// constant of [`exponential::FILTER_MEMORY_TAUS`]·τmin only: a slower "filter" is a bias that
    /// wanders, which `gauss_markov` (the same process, searched from there up) describes.
    fn search_range(&self, index: usize, tau_min: f64, _tau_max: f64) -> Option<(f64, f64)> {
        let slowest = exponential::FILTER_MEMORY_TAUS * tau_min;
        (index == 1).then(|| (1.0 / (2.0 * PI * slowest), 2.0 / tau_min))
    }
    /// White noise through a first-order low-pass, S(f) = n²/(1 + (f/f_c)²): no line.
    fn smooth_spectrum(&self) -> bool {
        true
    }
}

/// White rate noise of density `n` passed through a first-order low-pass of cut-off `cutoff_hz`,
/// output as the mean over each sample period (an integrating, decimating sensor).
///
/// Real sensors do not output white noise up to their Nyquist frequency: an analog and a digital
/// low-pass (the ADIS16405's Bartlett window FIR at 819.2 samples/s, for one) correlate neighbouring
/// samples, and the Allan variance near τ0 falls *below* N²/τ — a shape no power-law term has. This
/// effect replaces `white` where that shows: at long τ it is white noise of density `n`, and the
/// cut-off says how far below N²/τ the first τ points lie.
///
/// # Formula
/// ```text
/// σ²(τ) = n²/τ · [1 − T/(2τ)·(3 − 4·e^(−τ/T) + e^(−2τ/T))],   T = 1/(2π·f_c)
///       → n²/τ − 3n²T/(2τ²)   for τ ≫ T
/// ```
/// where n is the rate noise density before the filter (rad/s/√Hz), f_c the −3 dB frequency and T
/// the filter's time constant. The filtered rate is an Ornstein–Uhlenbeck process of variance
/// n²/(2T) (a Gauss–Markov process with q = n/T); the bracket is the Allan variance of its
/// averages over τ (IEEE Std 952-1997 Annex C, exponentially correlated noise, with q·T = n).
/// Averages, because the samples are taken as the mean of the filtered rate over each period τ0
/// (a decimation filter), which makes the mean of m samples the average over τ = m·τ0 and the
/// formula exact on the τ grid. Its general form: for filtered white noise whose normalised
/// autocorrelation g(s) has first absolute moment μ₁ = ∫|s|·g(s) ds, σ²(τ) = n²/τ − 3n²μ₁/(2τ²)
/// once τ exceeds the filter's memory (μ₁ = T for the first-order filter).
///
/// Simulated exactly (Gillespie's update of an Ornstein–Uhlenbeck process and its integral over
/// a period), by the code `gauss_markov` shares: the same process, read as a wandering bias
/// (`exponential.rs`).
///
/// # References
/// IEEE Std 952-1997, Annex C (exponentially correlated noise); D. T. Gillespie, "Exact numerical
/// simulation of the Ornstein-Uhlenbeck process and its integral", Phys. Rev. E 54(2), 1996;
/// Analog Devices, ADIS16405 data sheet Rev. B (2009): sensor bandwidth 330 Hz, internal sample
/// rate 819.2 SPS, Bartlett window FIR filter of 2^M taps per stage (SENS_AVG).
///
/// ```
/// use fdavar::model::effects::{Bandwidth, Effect};
/// let b = Bandwidth::new(1e-3, 50.0).unwrap();
/// let t = 1.0 / (2.0 * std::f64::consts::PI * 50.0);
/// // τ ≫ T: white noise less 3n²T/(2τ²).
/// let tau = 1.0;
/// let lead = 1e-6 / tau - 1.5e-6 * t / (tau * tau);
/// assert!((b.avar(tau).unwrap() / lead - 1.0).abs() < 1e-9);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bandwidth {
    n: f64,
    cutoff_hz: f64,
}

impl Bandwidth {
    /// Builds the effect from the density `n` (rad/s/√Hz) and the cut-off `cutoff_hz` (Hz).
    ///
    /// # Errors
    /// [`ParamError`] naming the parameter that is NaN or out of bounds.
    pub fn new(n: f64, cutoff_hz: f64) -> Result<Self, ParamError> {
        check_params(INFO.id, SCHEMA, &[n, cutoff_hz])?;
        Ok(Self { n, cutoff_hz })
    }

    /// The filter's time constant T = 1/(2π·f_c), s.
    pub fn time_constant_s(&self) -> f64 {
        1.0 / (2.0 * PI * self.cutoff_hz)
    }
}

impl Effect for Bandwidth {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.n, self.cutoff_hz])
    }
    fn avar(&self, tau: f64) -> Option<f64> {
        Some(self.n * self.n / tau * exponential::allan_bracket(tau / self.time_constant_s()))
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        exponential::add_period_means(self.n * self.n, self.time_constant_s(), ctx.dt, rng, out);
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "white rate noise of {:.3e}/√Hz seen through the sensor's own low-pass, cut-off \
                 {:.3} Hz: its filter correlates neighbouring samples, so the shortest averages \
                 are quieter than white noise would be",
                self.n, self.cutoff_hz
            ),
            // −1 only for τ ≫ T; no one slope (the fitter counts it as white noise, as it is).
            avar_slope: None,
            reference: "IEEE Std 952-1997 Annex C; Gillespie 1996",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn simulated_samples_have_the_predicted_variance_and_lag_one_correlation() {
        // Two exact moments of the sampled series, from the filtered rate's autocovariance
        // R(s) = n²/(2T)·e^(−|s|/T) integrated over one period and over two adjacent ones:
        // Var y = n²·[τ0 − T(1 − φ)]/τ0², Cov(y₀, y₁) = n²·T(1 − φ)²/(2τ0²). Tolerance: 5 times
        // a generous standard error of the sample moments over 2¹⁷ samples (2·√(2/n)·Var y).
        let (n, fc, dt) = (1e-2, 20.0, 0.01);
        let b = Bandwidth::new(n, fc).unwrap();
        let t = b.time_constant_s();
        let phi = (-dt / t).exp();
        let ctx = SimContext { dt, white_sigma: 0.0, temperature_c: None, accel: None };
        let mut y = vec![0.0; 1 << 17];
        b.simulate(&ctx, &mut rand_chacha::ChaCha8Rng::seed_from_u64(7), &mut y);
        let len = y.len() as f64;
        let var = y.iter().map(|v| v * v).sum::<f64>() / len;
        let cov = y.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / (len - 1.0);
        let var_true = n * n / (dt * dt) * (dt - t * (1.0 - phi));
        let cov_true = n * n / (dt * dt) * t * (1.0 - phi).powi(2) / 2.0;
        let se = var_true * (2.0 / len).sqrt() * 2.0;
        assert!((var - var_true).abs() < 5.0 * se, "{var} vs {var_true}");
        assert!((cov - cov_true).abs() < 5.0 * se, "{cov} vs {cov_true}");
    }

    #[test]
    fn a_fast_filter_is_white_noise() {
        let b = Bandwidth::new(1e-3, 1e5).unwrap();
        // Its deficit is 3T/(2τ) = 2.4·10⁻⁶/τ.
        for tau in [0.1, 1.0, 100.0] {
            assert!((b.avar(tau).unwrap() * tau / 1e-6 - 1.0).abs() < 1e-4);
        }
    }
}

//! `quantization` (Q): angle quantization, the rounding of the sensor's output.

use super::{
    check_params, params_of, Domain, Effect, EffectKind, Evidence, Explanation, KindInfo, Param,
    ParamError, ParamSpec, SimContext, SimStage,
};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[ParamSpec {
    name: "q",
    unit: "rad",
    bounds: (0.0, 10.0),
    doc: "angle quantization noise Q (rms of the angle rounding error)",
}];

/// The registry entry of [`Quantization`].
pub(super) static KIND: KindInfo = KindInfo {
    id: "quantization",
    alias: Some("Q"),
    schema: SCHEMA,
    domain: Domain::Spectral,
    evidence: Evidence::None,
    stage: SimStage::Output,
    construct: |v| Ok(Box::new(Quantization::new(v[0])?)),
};

/// Angle quantization noise `q`: the sensor reports its output in whole LSBs.
///
/// A digital gyro counts angle increments (or rounds its rate output to an LSB Δ while carrying
/// the remainder to the next sample), so the *angle* it reports is rounded to a step δ = Δ·τ0. The
/// rounding error of the angle is uniform on ±δ/2 and, once the other noise moves the angle by more
/// than δ per sample, independent from sample to sample: white phase noise, seen at short τ.
///
/// # Formula
/// ```text
/// σ²(τ) = 3·q² / τ²
/// q = δ / √12 = Δ·τ0 / √12        Δ = q·√12 / τ0
/// simulated: s[n] = round(Σ_{k≤n} y[k] / Δ),  y_out[n] = Δ·(s[n] − s[n−1])
/// ```
/// where y is the sum of the axis's other effects (rate), Δ the rate LSB, τ0 the sample period and
/// δ the angle step. Every output value is a whole multiple of Δ and the angle Σ y_out·τ0 is the true
/// angle rounded to δ, so its error e[n] has variance q² and σ²(τ) = E[(e[i+2m] − 2e[i+m] + e[i])²] /
/// (2τ²) = 6q²/(2τ²). Rounding each rate sample on its own (no carry) was rejected: its error is
/// white *rate* noise of variance Δ²/12, an N term (σ² ∝ 1/τ), not the Q term.
///
/// # References
/// IEEE Std 952-1997, Annex C.1 (quantization noise); Riley, NIST SP 1065, 2008, Table 5 (white PM).
///
/// ```
/// use fdavar::model::effects::{Effect, Quantization};
/// let q = Quantization::new(1e-4).unwrap();
/// assert!((q.avar(0.1).unwrap() - 3e-6).abs() < 1e-18);
/// assert!((q.lsb(0.01) - 1e-4 * 12f64.sqrt() / 0.01).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantization {
    q: f64,
}

impl Quantization {
    /// Builds the effect from the angle quantization `q` in rad.
    ///
    /// # Errors
    /// [`ParamError`] naming `q` when it is NaN or outside [0, 10].
    pub fn new(q: f64) -> Result<Self, ParamError> {
        check_params(KIND.id, SCHEMA, &[q])?;
        Ok(Self { q })
    }

    /// The angle quantization Q, rad.
    pub fn q(&self) -> f64 {
        self.q
    }

    /// The rate LSB Δ = q·√12 / τ0 that gives this Q at sample period `dt`.
    pub fn lsb(&self, dt: f64) -> f64 {
        self.q * 12f64.sqrt() / dt
    }
}

impl Effect for Quantization {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.q])
    }
    fn avar(&self, tau: f64) -> Option<f64> {
        Some(3.0 * self.q * self.q / (tau * tau))
    }
    fn simulate(&self, ctx: &SimContext<'_>, _rng: &mut dyn RngCore, out: &mut [f64]) {
        let lsb = self.lsb(ctx.dt);
        if lsb <= 0.0 {
            return;
        }
        let mut angle_lsb = 0.0; // true angle so far, in steps δ
        let mut reported = 0.0; // rounded angle reported so far, in steps δ
        for y in out.iter_mut() {
            angle_lsb += *y / lsb;
            let now = angle_lsb.round();
            *y = lsb * (now - reported);
            reported = now;
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "angle quantization of {:.3e} rms: the sensor reports whole output steps, so its \
                 integrated output carries a rounding error that dominates the shortest averaging times",
                self.q
            ),
            avar_slope: Some(-2.0),
            reference: "IEEE Std 952-1997 Annex C.1",
        }
    }
}

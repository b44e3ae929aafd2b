//! `noise_burst`: a span of time in which the white noise is louder.

use super::{
    check_params, first_index_at, params_of, std_normal, Domain, Effect, EffectKind, Evidence,
    Explanation, KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage,
};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[
    ParamSpec {
        name: "start_s",
        unit: "s",
        bounds: (0.0, 1e9),
        doc: "start of the burst, seconds from the first sample",
    },
    ParamSpec {
        name: "end_s",
        unit: "s",
        bounds: (0.0, 1e9),
        doc: "end of the burst (exclusive), seconds from the first sample",
    },
    ParamSpec {
        name: "factor",
        unit: "1",
        bounds: (1.0, 1e3),
        doc: "white noise level inside the span over the level outside (σ ratio, ≥ 1)",
    },
];

/// The registry entry of [`NoiseBurst`].
pub(super) static KIND: KindInfo = KindInfo {
    id: "noise_burst",
    alias: None,
    schema: SCHEMA,
    domain: Domain::TimeDomain,
    evidence: Evidence::Events,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(NoiseBurst::new(v[0], v[1], v[2])?)),
};

/// The white noise level multiplied by `factor` between `start_s` and `end_s`: vibration from a
/// motor that runs for a while, electrical interference — the seed paper's test signal.
///
/// It is what the F-DAVAR window adapts to: the variance ratio F rises inside the span.
///
/// # Formula
/// ```text
/// y[n] += σ_w·√(factor² − 1)·w[n]   for start_s ≤ n·τ0 < end_s,  w ~ N(0, 1)
/// ```
/// where σ_w = N/√τ0 is the per-sample deviation of the axis's `white` term, so that the white
/// deviation inside the span is factor·σ_w. Being additive, a burst can only make the noise louder
/// (factor ≥ 1); a quiet span is a burst over the rest of the record.
///
/// # References
/// Yang H. et al., Electronics Optics & Control 23(10), 2016 (the seed; noise tripled over samples
/// 1200–2400); Galleani L., IEEE TUFFC 56(3), 2009.
///
/// ```
/// use fdavar::model::effects::{Effect, NoiseBurst};
/// assert!(NoiseBurst::new(10.0, 5.0, 3.0).is_err()); // ends before it starts
/// assert!(NoiseBurst::new(36.0, 72.0, 3.0).is_ok());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseBurst {
    start_s: f64,
    end_s: f64,
    factor: f64,
}

impl NoiseBurst {
    /// Builds the effect from the span `start_s`..`end_s` (s) and the σ ratio `factor`.
    ///
    /// # Errors
    /// [`ParamError`] naming the parameter that is NaN or out of bounds, or
    /// [`ParamError::Invalid`] when `end_s` ≤ `start_s`.
    pub fn new(start_s: f64, end_s: f64, factor: f64) -> Result<Self, ParamError> {
        check_params(KIND.id, SCHEMA, &[start_s, end_s, factor])?;
        if end_s <= start_s {
            return Err(ParamError::Invalid {
                effect: KIND.id,
                reason: format!("end_s = {end_s} must be after start_s = {start_s}"),
            });
        }
        Ok(Self {
            start_s,
            end_s,
            factor,
        })
    }

    /// Start of the span, seconds from the first sample.
    pub fn start_s(&self) -> f64 {
        self.start_s
    }

    /// End of the span (exclusive), seconds from the first sample.
    pub fn end_s(&self) -> f64 {
        self.end_s
    }

    /// The σ ratio inside the span.
    pub fn factor(&self) -> f64 {
        self.factor
    }
}

impl Effect for NoiseBurst {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.start_s, self.end_s, self.factor])
    }
    fn avar(&self, _tau: f64) -> Option<f64> {
        None
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        let start = first_index_at(self.start_s, ctx.dt, out.len());
        let end = first_index_at(self.end_s, ctx.dt, out.len());
        let extra = ctx.white_sigma * (self.factor * self.factor - 1.0).sqrt();
        for y in &mut out[start..end] {
            *y += extra * std_normal(rng);
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "the white noise was {:.2} times louder from {:.3} s to {:.3} s: vibration or \
                 interference for a while",
                self.factor, self.start_s, self.end_s
            ),
            avar_slope: None,
            reference: "Yang et al. 2016 (seed); Galleani, IEEE TUFFC 56(3), 2009",
        }
    }
}

//! Reference effect kinds and a tiny signal generator for the model workbench's tests.
//!
//! The fitter and the diagnosis only see `&dyn EffectKind` / `&dyn Effect`, and they take the
//! registry as an argument. These kinds implement the DESIGN §4 vocabulary (same ids, aliases,
//! parameter names and Allan signatures) so that the workbench can be tested on its own, and so
//! that its tests keep a second, independent statement of the signatures once the effect files of
//! [`crate::model::effects`] fill [`crate::model::effects::REGISTRY`].
//!
//! Not part of the stable API (hidden from the docs).

use crate::model::effects::{
    check_params, Domain, Effect, EffectKind, Evidence, Explanation, Param, ParamError, ParamSpec,
    SimContext,
};
use rand::RngCore;
use rand_distr::{Distribution, StandardNormal};
use std::f64::consts::{LN_2, PI};

/// One test effect kind: a row of DESIGN §4 as data.
#[derive(Debug)]
pub struct Kind {
    id: &'static str,
    alias: Option<&'static str>,
    schema: &'static [ParamSpec],
    domain: Domain,
    evidence: Evidence,
    slope: Option<f64>,
    avar: Option<fn(&[f64], f64) -> f64>,
}

const fn p(name: &'static str, unit: &'static str, low: f64, high: f64) -> ParamSpec {
    ParamSpec { name, unit, bounds: (low, high), doc: "" }
}

/// Every test kind, base terms first (the order of the real registry).
pub static KINDS: &[&dyn EffectKind] = &[
    &QUANT, &WHITE, &BIAS, &RW, &RAMP, &SINE, &GM, &STEP, &BURST, &TEMP, &GSENS,
];

static ALL: [&Kind; 11] = [
    &QUANT, &WHITE, &BIAS, &RW, &RAMP, &SINE, &GM, &STEP, &BURST, &TEMP, &GSENS,
];

static QUANT: Kind = Kind {
    id: "quantization", alias: Some("Q"), schema: &[p("q", "rad", 0.0, 1.0)],
    domain: Domain::Spectral, evidence: Evidence::None, slope: Some(-2.0),
    avar: Some(|v, t| 3.0 * v[0] * v[0] / (t * t)),
};
static WHITE: Kind = Kind {
    id: "white", alias: Some("N"), schema: &[p("n", "rad/s/sqrt(Hz)", 0.0, 10.0)],
    domain: Domain::Spectral, evidence: Evidence::None, slope: Some(-1.0),
    avar: Some(|v, t| v[0] * v[0] / t),
};
static BIAS: Kind = Kind {
    id: "bias_instability", alias: Some("B"), schema: &[p("b", "rad/s", 0.0, 10.0)],
    domain: Domain::Spectral, evidence: Evidence::None, slope: Some(0.0),
    avar: Some(|v, _| 2.0 * LN_2 / PI * v[0] * v[0]),
};
static RW: Kind = Kind {
    id: "random_walk", alias: Some("K"), schema: &[p("k", "rad/s/sqrt(s)", 0.0, 10.0)],
    domain: Domain::Spectral, evidence: Evidence::None, slope: Some(1.0),
    avar: Some(|v, t| v[0] * v[0] * t / 3.0),
};
static RAMP: Kind = Kind {
    id: "ramp", alias: Some("R"), schema: &[p("r", "rad/s^2", 0.0, 10.0)],
    domain: Domain::Spectral, evidence: Evidence::None, slope: Some(2.0),
    avar: Some(|v, t| v[0] * v[0] * t * t / 2.0),
};
static SINE: Kind = Kind {
    id: "sinusoid", alias: None,
    schema: &[p("amplitude", "rad/s", 0.0, 100.0), p("frequency_hz", "Hz", 1e-9, 1e4)],
    domain: Domain::Spectral, evidence: Evidence::None, slope: None,
    avar: Some(|v, t| {
        let x = PI * v[1] * t;
        let s = x.sin();
        v[0] * v[0] * (s * s / x).powi(2)
    }),
};
static GM: Kind = Kind {
    id: "gauss_markov", alias: None,
    schema: &[p("sigma", "rad/s", 0.0, 100.0), p("time_constant_s", "s", 1e-6, 1e9)],
    domain: Domain::Spectral, evidence: Evidence::None, slope: None,
    avar: Some(|v, t| {
        let (s, tc) = (v[0], v[1]);
        let q2 = 2.0 * s * s / tc;
        let r = t / tc;
        q2 * tc * tc / t * (1.0 - (3.0 - 4.0 * (-r).exp() + (-2.0 * r).exp()) / (2.0 * r))
    }),
};
static STEP: Kind = Kind {
    id: "bias_step", alias: None,
    schema: &[p("time_s", "s", 0.0, 1e9), p("size", "rad/s", -100.0, 100.0)],
    domain: Domain::TimeDomain, evidence: Evidence::None, slope: None, avar: None,
};
static BURST: Kind = Kind {
    id: "noise_burst", alias: None,
    schema: &[p("start_s", "s", 0.0, 1e9), p("end_s", "s", 0.0, 1e9), p("factor", "1", 1.0, 1e3)],
    domain: Domain::TimeDomain, evidence: Evidence::Events, slope: None, avar: None,
};
static TEMP: Kind = Kind {
    id: "temperature", alias: None, schema: &[p("coefficient_per_k", "rad/s/K", -100.0, 100.0)],
    domain: Domain::TimeDomain, evidence: Evidence::Temperature, slope: None, avar: None,
};
static GSENS: Kind = Kind {
    id: "g_sensitivity", alias: None,
    schema: &[p("source", "axis", 0.0, 2.0), p("coefficient", "(rad/s)/(m/s^2)", -100.0, 100.0)],
    domain: Domain::TimeDomain, evidence: Evidence::Accel, slope: None, avar: None,
};

impl EffectKind for Kind {
    fn id(&self) -> &'static str {
        self.id
    }
    fn alias(&self) -> Option<&'static str> {
        self.alias
    }
    fn schema(&self) -> &'static [ParamSpec] {
        self.schema
    }
    fn domain(&self) -> Domain {
        self.domain
    }
    fn evidence(&self) -> Evidence {
        self.evidence
    }
    fn build(&self, values: &[f64]) -> Result<Box<dyn Effect>, ParamError> {
        check_params(self.id, self.schema, values)?;
        let kind = ALL
            .iter()
            .copied()
            .find(|k| k.id == self.id)
            .expect("every test kind is in ALL");
        Ok(Box::new(Eff { kind, values: values.to_vec() }))
    }
}

/// A test effect: a kind and its values.
#[derive(Debug)]
pub struct Eff {
    kind: &'static Kind,
    values: Vec<f64>,
}

fn uniform(rng: &mut dyn RngCore) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

fn normal(rng: &mut dyn RngCore) -> f64 {
    StandardNormal.sample(rng)
}

impl Effect for Eff {
    fn kind(&self) -> &'static dyn EffectKind {
        self.kind
    }
    fn params(&self) -> Vec<Param> {
        self.kind
            .schema
            .iter()
            .zip(&self.values)
            .map(|(&spec, &value)| Param { spec, value })
            .collect()
    }
    fn avar(&self, tau: f64) -> Option<f64> {
        self.kind.avar.map(|f| f(&self.values, tau))
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        let v = &self.values;
        let dt = ctx.dt;
        let time = |i: usize| i as f64 * dt;
        match self.kind.id {
            "quantization" => {
                // The statistical model behind 3Q²/τ²: a white angle error of variance Q² (uniform
                // rounding error, dithered by the signal), differenced into the rate.
                let half = v[0] * 3f64.sqrt();
                let mut prev = 0.0;
                for y in out.iter_mut() {
                    let e = half * (2.0 * uniform(rng) - 1.0);
                    *y += (e - prev) / dt;
                    prev = e;
                }
            }
            "white" => out.iter_mut().for_each(|y| *y += v[0] / dt.sqrt() * normal(rng)),
            "bias_instability" => {
                // 1/f from a sum of first-order Gauss–Markov processes, 3 per decade.
                let ratio = 10f64.powf(1.0 / 3.0);
                // One-sided S_y(f) = B²/(π f) (IEEE 952: two-sided B²/(2π f)); a GM of variance σ² and
                // time constant T has one-sided PSD 4σ²T/(1+(2πfT)²), and a log-spaced sum of them
                // with ratio r integrates to σ²/(f·ln r).
                let sigma = (v[0] * v[0] * ratio.ln() / PI).sqrt();
                let mut tc = dt;
                let span = out.len() as f64 * dt * 30.0;
                while tc < span {
                    add_gauss_markov(sigma, tc, dt, rng, out);
                    tc *= ratio;
                }
            }
            "random_walk" => {
                let mut b = 0.0;
                for y in out.iter_mut() {
                    b += v[0] * dt.sqrt() * normal(rng);
                    *y += b;
                }
            }
            "ramp" => out.iter_mut().enumerate().for_each(|(i, y)| *y += v[0] * time(i)),
            "sinusoid" => out
                .iter_mut()
                .enumerate()
                .for_each(|(i, y)| *y += v[0] * (2.0 * PI * v[1] * time(i)).sin()),
            "gauss_markov" => add_gauss_markov(v[0], v[1], dt, rng, out),
            "bias_step" => out
                .iter_mut()
                .enumerate()
                .filter(|(i, _)| time(*i) >= v[0])
                .for_each(|(_, y)| *y += v[1]),
            "noise_burst" => {
                let extra = ctx.white_sigma * (v[2] * v[2] - 1.0).sqrt();
                for (i, y) in out.iter_mut().enumerate() {
                    if time(i) >= v[0] && time(i) < v[1] {
                        *y += extra * normal(rng);
                    }
                }
            }
            "temperature" => {
                if let Some(t) = ctx.temperature_c {
                    let t0 = t.first().copied().unwrap_or(0.0);
                    out.iter_mut().zip(t).for_each(|(y, c)| *y += v[0] * (c - t0));
                }
            }
            "g_sensitivity" => {
                if let Some(acc) = ctx.accel {
                    let src = acc[v[0].round() as usize];
                    out.iter_mut().zip(src).for_each(|(y, a)| *y += v[1] * a);
                }
            }
            _ => {}
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!("{} with {:?}", self.kind.id, self.values),
            avar_slope: self.kind.slope,
            reference: "IEEE Std 952-1997 Annex C",
        }
    }
}

fn add_gauss_markov(sigma: f64, tc: f64, dt: f64, rng: &mut dyn RngCore, out: &mut [f64]) {
    let phi = (-dt / tc).exp();
    let drive = sigma * (1.0 - phi * phi).sqrt();
    let mut b = sigma * normal(rng);
    for y in out.iter_mut() {
        *y += b;
        b = phi * b + drive * normal(rng);
    }
}

/// Builds a test effect from a name and values (panics on a bad name: tests only).
pub fn effect(name: &str, values: &[f64]) -> Box<dyn Effect> {
    KINDS
        .iter()
        .find(|k| k.id() == name || k.alias() == Some(name))
        .unwrap_or_else(|| panic!("no test kind {name}"))
        .build(values)
        .unwrap_or_else(|e| panic!("{e}"))
}

/// Sums the effects into `n` rate samples (quantization, if present, should come last).
pub fn simulate(
    effects: &[Box<dyn Effect>],
    ctx: &SimContext<'_>,
    rng: &mut dyn RngCore,
    n: usize,
) -> Vec<f64> {
    let mut out = vec![0.0; n];
    for e in effects {
        e.simulate(ctx, rng, &mut out);
    }
    out
}

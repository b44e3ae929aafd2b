//! The JSON of `fdavar fit` / `fdavar diagnose` (docs/design.md §7, **contract**) and the figures' data.
//!
//! `{"axes": [{"axis", "model": [names], "fit_error", "span_fit_error", "coefficients": {effect: {param: P}},
//! "failing_tau": [[lo, hi]], "failing_spans": [[start_s, end_s]], "events": [{"effect",
//! ...params}], "suggestions": [{"effect", "params": {param: P}, "fit_error_after",
//! "span_fit_error_after", "explanation"}]}]}`, where every parameter P is `{"value", "sigma", "unit"}` ([`param_json`]);
//! `fit` omits `suggestions`; `"rate_excess_kurtosis"` appears on an axis with heavy-tailed noise. Values are SI. Plain data, built from a [`FittedModel`] /
//! [`Diagnosis`]; no I/O here.

use crate::model::diagnose::Diagnosis;
use crate::model::fit::{FittedModel, ParamValue};
use crate::report::figure::{AllanComparison, AllanFigure, MeasuredPoint, ModelCurves, SpanScore, Term};
use serde::Serialize;
use serde_json::{Map, Value};

/// The top-level JSON object.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// One entry per analysed axis.
    pub axes: Vec<AxisReport>,
}

/// One axis of the JSON.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisReport {
    /// Axis name.
    pub axis: String,
    /// Effect ids of the model.
    pub model: Vec<String>,
    /// **contract** fit_error: the whole record's τ grid.
    pub fit_error: f64,
    /// The spans' pooled RMS of z ([`FittedModel::span_fit_error`]): where in time the model
    /// holds (beyond the contract); absent when the record was too short to be checked on spans.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub span_fit_error: Option<f64>,
    /// effect → parameter → `{"value", "sigma", "unit"}` ([`param_json`]).
    pub coefficients: Map<String, Value>,
    /// **contract** failing τ intervals, seconds.
    pub failing_tau: Vec<[f64; 2]>,
    /// Time intervals (seconds from the first sample) where the spans' fit_error exceeds 3.
    pub failing_spans: Vec<[f64; 2]>,
    /// Events: `{"effect": id, param: value, …}`.
    pub events: Vec<Map<String, Value>>,
    /// Excess kurtosis of the white rate noise, present only when it is measurably above a
    /// Gaussian's 0 ([`FittedModel::rate_excess_kurtosis`]): isolated spikes, for which every
    /// interval and z was widened.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rate_excess_kurtosis: Option<f64>,
    /// Suggestions, best first (diagnose only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub suggestions: Option<Vec<Map<String, Value>>>,
}

fn number(v: f64) -> Value {
    serde_json::Number::from_f64(v).map_or(Value::Null, Value::Number)
}

/// One fitted parameter as the JSON writes it: `{"value", "sigma", "unit"}`.
///
/// `value` is SI in `unit` (the parameter's unit on its axis, as the text and the node's
/// `Coefficient` message give it), or the axis name for an axis-valued parameter (`g_sensitivity`'s
/// `source`: `"accel_x"`, unit `"axis"`); `sigma` is the fit's 1σ in the same unit, `null` where
/// the fit gives none. A `value` of 0 with a `sigma` is a term the fit could not resolve: below
/// [`ParamValue::upper_bound`].
pub fn param_json(p: &ParamValue) -> Value {
    let value = p
        .axis()
        .map_or_else(|| number(p.value), |a| Value::String(a.name().to_string()));
    let mut m = Map::new();
    m.insert("value".into(), value);
    m.insert("sigma".into(), p.sigma.map_or(Value::Null, number));
    m.insert("unit".into(), Value::String(p.unit.clone()));
    Value::Object(m)
}

/// A list of parameters as a JSON object keyed by name.
fn params_json(params: &[ParamValue]) -> Value {
    Value::Object(params.iter().map(|p| (p.name.clone(), param_json(p))).collect())
}

impl AxisReport {
    /// The JSON entry of a fitted model (no suggestions).
    pub fn from_fit(fit: &FittedModel) -> Self {
        let coefficients = fit
            .terms
            .iter()
            .map(|t| (t.effect.clone(), params_json(&t.params)))
            .collect();
        let events = fit
            .events
            .iter()
            .map(|e| {
                let mut m = Map::new();
                m.insert("effect".into(), Value::String(e.effect.clone()));
                for (k, v) in &e.params {
                    m.insert(k.clone(), number(*v));
                }
                m
            })
            .collect();
        AxisReport {
            axis: fit.axis.name().to_string(),
            model: fit.spec.ids().to_vec(),
            fit_error: fit.fit_error,
            span_fit_error: fit.span_fit_error,
            coefficients,
            failing_tau: fit.failing_tau.clone(),
            failing_spans: fit
                .failing_spans
                .iter()
                .map(|s| [s.start_s, s.end_s])
                .collect(),
            events,
            rate_excess_kurtosis: (fit.rate_excess_kurtosis > 0.0).then_some(fit.rate_excess_kurtosis),
            suggestions: None,
        }
    }

    /// The JSON entry of a diagnosis (with suggestions).
    pub fn from_diagnosis(d: &Diagnosis) -> Self {
        let mut r = Self::from_fit(&d.fit);
        r.suggestions = Some(
            d.suggestions
                .iter()
                .map(|s| {
                    let mut m = Map::new();
                    m.insert("effect".into(), Value::String(s.effect.clone()));
                    m.insert("params".into(), params_json(&s.params));
                    m.insert("fit_error_after".into(), number(s.fit_error_after));
                    if let Some(spans) = s.span_fit_error_after {
                        m.insert("span_fit_error_after".into(), number(spans));
                    }
                    m.insert("explanation".into(), Value::String(s.explanation.clone()));
                    m.insert("given".into(), s.given.iter().cloned().map(Value::String).collect());
                    m
                })
                .collect(),
        );
        r
    }
}

/// The measured deviations of a fit, for the figures.
pub fn measured_points(fit: &FittedModel) -> Vec<MeasuredPoint> {
    fit.points
        .iter()
        .map(|p| {
            let (low, high) = p.ci();
            MeasuredPoint {
                tau: p.tau,
                dev: p.measured.sqrt(),
                dev_low: low.max(0.0).sqrt(),
                dev_high: high.sqrt(),
                bridged: p.bridged,
            }
        })
        .collect()
}

/// A fitted model's curves, residuals and error, for the figures.
pub fn model_curves(fit: &FittedModel) -> ModelCurves {
    let tau: Vec<f64> = fit.points.iter().map(|p| p.tau).collect();
    ModelCurves {
        label: fit
            .terms
            .iter()
            .map(|t| t.alias.clone().unwrap_or_else(|| t.effect.clone()))
            .collect::<Vec<_>>()
            .join(" + "),
        total: fit.points.iter().map(|p| (p.tau, p.model.max(0.0).sqrt())).collect(),
        terms: fit
            .terms
            .iter()
            .filter(|t| !t.curve.is_empty())
            .map(|t| Term {
                name: t.alias.clone().unwrap_or_else(|| t.effect.clone()),
                curve: tau.iter().zip(&t.curve).map(|(&x, &v)| (x, v.max(0.0).sqrt())).collect(),
            })
            .collect(),
        z: fit.points.iter().map(|p| (p.tau, p.z)).collect(),
        failing_tau: fit.failing_tau.iter().map(|r| (r[0], r[1])).collect(),
        fit_error: fit.fit_error,
        span_fit_error: fit.span_fit_error,
        spans: fit
            .spans
            .iter()
            .map(|c| SpanScore {
                start_s: c.span.start_s,
                end_s: c.span.end_s,
                fit_error: c.fit_error,
                louder: c.mean_z >= 0.0,
            })
            .collect(),
        failing_spans: fit.failing_spans.iter().map(|s| (s.start_s, s.end_s)).collect(),
    }
}

/// The Allan figure of one fitted axis.
pub fn allan_figure(fit: &FittedModel, title: &str) -> AllanFigure {
    AllanFigure {
        axis: fit.axis.name().to_string(),
        unit: fit.axis.rate_unit().to_string(),
        title: title.to_string(),
        measured: measured_points(fit),
        model: model_curves(fit),
    }
}

/// The before/after figure of a suggestion.
pub fn comparison_figure(before: &FittedModel, after: &FittedModel, title: &str) -> AllanComparison {
    AllanComparison {
        axis: before.axis.name().to_string(),
        unit: before.axis.rate_unit().to_string(),
        title: title.to_string(),
        measured: measured_points(before),
        // A time-domain effect is fitted after removing it from the samples: show that residual.
        after_measured: (after.points.len() != before.points.len()
            || after.points.iter().zip(&before.points).any(|(a, b)| (a.tau, a.measured) != (b.tau, b.measured)))
        .then(|| measured_points(after)),
        before: model_curves(before),
        after: model_curves(after),
    }
}

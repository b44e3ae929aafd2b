//! The time-resolved check of a whole-record model: the cleaned record cut into half-overlapping
//! spans, each with its own Allan variance, and the model's z on each.
//!
//! Why: the whole-record Allan variance averages over time, so a burst, a step or a warm-up that a
//! stationary model absorbs on the whole record still fails inside the span where it happens.
//! The model is fitted once, on the whole record; the spans only check it ([`check_span`]), and
//! their z values are pooled into `fit_error` (see [`FittedModel::fit_error`] for why pooled).
//!
//! [`FittedModel::fit_error`]: super::FittedModel::fit_error

use super::scoring::{rms, z_scores, FAILING_Z};
use super::types::{FitOptions, Span};
use super::CurveFit;
use crate::allan::edf::edf_with_fourth_cumulant;
use crate::allan::{oavar_rate_variances_with_spans_in, AllanPoint};
use crate::model::measure::{edf_for_mix, NoiseClass};
use serde::{Deserialize, Serialize};

/// Spans the record is cut into for the time-resolved check of the model (plus the 7 spans
/// straddling their boundaries).
///
/// Eight spans of a 20–60 min record are 2.5–7.5 min each: long enough for their own Allan
/// variance to reach τ of ten seconds with a useful EDF, short enough that a step, a burst or a
/// warm-up fills a good part of one span instead of a sliver of the record.
pub const DEFAULT_SPANS: usize = 8;

/// Least EDF of a span's τ point for it to count in the span check.
///
/// z of an estimate with ν degrees of freedom has skewness √(8/ν), and at small ν the EDF of a
/// short span's flicker-dominated points is least trustworthy. Measured on 72 clean simulated
/// axes (12 seeds, 200 Hz, 20 min, N+B+K): with ν ≥ 20 the span RMS has median 1.05, p90 1.20,
/// max 1.41; ν ≥ 4 adds nothing to what a step or warm-up shows (4.30 → 4.55 for a 2·10⁻³ rad/s step).
pub const MIN_SPAN_EDF: f64 = 20.0;

/// Fewest samples in one span; a shorter record is cut into fewer spans.
pub const MIN_SPAN_SAMPLES: usize = 1024;

/// The model checked on one span of the record.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpanCheck {
    /// The span, seconds from the first sample.
    pub span: Span,
    /// RMS of z over the span's own τ grid, the model being the whole-record fit.
    pub fit_error: f64,
    /// Mean of those z: its sign tells a span louder than the model (+) from a quieter one (−),
    /// which the RMS cannot (0 without points).
    #[serde(default)]
    pub mean_z: f64,
    /// The span's most significant departure from the model: the τ of its point with the
    /// largest |z|, in seconds, and that point's measured / model Allan variance (1.37: 37 %
    /// louder). 0 and 1 without points.
    ///
    /// Why beside z: z says whether a departure is resolved, not whether it matters. An hour at
    /// 100 Hz resolves a span's short-τ Allan variance to about 1 %, so a real sensor whose noise
    /// drifts by a few percent fails the span check, where a burst or a step departs by tens of
    /// percent or more.
    #[serde(default)]
    pub worst_tau: f64,
    /// See [`SpanCheck::worst_tau`].
    #[serde(default = "as_the_model")]
    pub worst_ratio: f64,
}

/// [`SpanCheck::worst_ratio`] of a span without points, and of checks written before it existed.
fn as_the_model() -> f64 {
    1.0
}

/// The Allan variance of one span of the cleaned record.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct SpanMeasure {
    span: Span,
    points: Vec<AllanPoint>,
}

/// Measures the Allan variance of the cleaned `series` at `factors` and of each of its spans on
/// the record's τ grid: the record's points, the factors that were bridged, the spans.
///
/// The record is cut into `opts.spans` equal spans (fewer if a span would hold fewer than
/// [`MIN_SPAN_SAMPLES`]; none below two). Why spans: the whole-record Allan variance averages over
/// time. A noise burst only raises the white level, a bias step reads as a rate random walk, a
/// warm-up as flicker and random walk; a stationary model then fits the whole record and still
/// fails inside the span where the record is not stationary. The model, fitted once on the whole
/// record, must also explain each span. Spans overlap by half, so that a change on a boundary
/// sits in the middle of another span. Record and spans are measured in one pass
/// ([`oavar_rate_variances_with_spans_in`]); `phase` is its scratch.
pub(super) fn measure_with_spans(
    series: &[f64],
    tau0: f64,
    factors: &[usize],
    opts: &FitOptions,
    phase: &mut Vec<f64>,
) -> (Vec<AllanPoint>, Vec<usize>, Vec<SpanMeasure>) {
    let n = series.len();
    let count = opts.spans.min(n / MIN_SPAN_SAMPLES);
    // Half-overlapping: a change at a span boundary still falls in the middle of one span.
    let spans: Vec<(std::ops::Range<usize>, Vec<usize>)> = if count < 2 {
        Vec::new()
    } else {
        (0..2 * count - 1)
            .map(|i| {
                let (a, b) = (i * n / (2 * count), (i + 2) * n / (2 * count));
                let max_m = ((b - a) as f64 * opts.max_m_fraction).floor() as usize;
                (a..b, opts.grid.factors(max_m.max(1)))
            })
            .collect()
    };
    let (record, measured) = oavar_rate_variances_with_spans_in(series, tau0, factors, &spans, phase);
    let spans = spans
        .iter()
        .zip(measured)
        .map(|((range, _), points)| SpanMeasure {
            span: Span {
                start_s: range.start as f64 * tau0,
                end_s: range.end as f64 * tau0,
            },
            points: points.into_iter().map(|p| p.point).collect(),
        })
        .collect();
    let (points, bridged) = super::with_bridged(record);
    (points, bridged, spans)
}

/// The whole-record model of `fit` checked on one span: z at each of the span's τ (those with an
/// EDF of at least [`MIN_SPAN_EDF`]), with the EDF of the model's noise mix for the span's length.
/// Returns the span's RMS and its z values (pooled by the caller).
pub(super) fn check_span(measure: &SpanMeasure, fit: &CurveFit) -> (SpanCheck, Vec<f64>) {
    // Each counted point's z, τ and measured / model.
    let (z, departures): (Vec<f64>, Vec<(f64, f64)>) = measure
        .points
        .iter()
        .filter(|p| p.avar.is_finite() && p.avar > 0.0)
        .filter_map(|p| {
            let i = fit.points.iter().position(|q| q.m == p.m)?;
            let parts: Vec<(f64, NoiseClass)> = fit
                .terms
                .iter()
                .zip(&fit.classes)
                .map(|(t, &c)| (t.curve[i], c))
                .collect();
            let model = fit.points[i].model;
            let edf = edf_with_fourth_cumulant(edf_for_mix(&parts, p.terms + 2 * p.m, p.m), model, p.m, p.terms, fit.fourth_cumulant);
            let z = (edf >= MIN_SPAN_EDF).then(|| z_scores(&[p.avar], &[model], &[edf]))?.pop()?;
            Some((z, (p.tau, p.avar / model)))
        })
        .unzip();
    let mean_z = if z.is_empty() { 0.0 } else { z.iter().sum::<f64>() / z.len() as f64 };
    let (worst_tau, worst_ratio) = z
        .iter()
        .zip(&departures)
        .filter(|(_, (_, ratio))| ratio.is_finite())
        .max_by(|a, b| a.0.abs().total_cmp(&b.0.abs()))
        .map_or((0.0, 1.0), |(_, &d)| d);
    let check = SpanCheck {
        span: measure.span,
        fit_error: rms(&z),
        mean_z,
        worst_tau,
        worst_ratio,
    };
    (check, z)
}

/// Maximal runs of spans whose fit_error exceeds [`FAILING_Z`], merged into time intervals.
pub(super) fn failing_spans(spans: &[SpanCheck]) -> Vec<Span> {
    let mut out: Vec<Span> = Vec::new();
    for s in spans.iter().filter(|s| s.fit_error > FAILING_Z) {
        match out.last_mut() {
            Some(last) if last.end_s >= s.span.start_s => last.end_s = s.span.end_s,
            _ => out.push(s.span),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::fit::{FitPoint, FittedTerm};
    use crate::model::effects::Domain;
    use crate::model::measure::edf_oavar;
    use crate::allan::oavar_rate;

    fn check(start_s: f64, end_s: f64, fit_error: f64) -> SpanCheck {
        SpanCheck { span: Span { start_s, end_s }, fit_error, mean_z: fit_error, worst_tau: 0.0, worst_ratio: 1.0 }
    }

    #[test]
    fn failing_spans_merge_overlapping_and_touching_runs() {
        let spans = [
            check(0.0, 2.0, 1.0),
            check(1.0, 3.0, 4.0),
            check(2.0, 4.0, 5.0),
            check(3.0, 5.0, 1.0),
            check(4.0, 6.0, 3.0), // exactly FAILING_Z: holds
            check(5.0, 7.0, 3.5),
        ];
        assert_eq!(
            failing_spans(&spans),
            [Span { start_s: 1.0, end_s: 4.0 }, Span { start_s: 5.0, end_s: 7.0 }]
        );
    }

    #[test]
    fn spans_overlap_by_half_and_need_enough_samples() {
        let opts = FitOptions::default();
        // 4096 samples hold 4 spans of 1024 (not DEFAULT_SPANS = 8): 7 half-overlapping spans.
        let series: Vec<f64> = (0..4096).map(|i| (i % 7) as f64 + 1e-3 * ((i * 7919) % 101) as f64).collect();
        let factors = opts.grid.factors(4096 / 3);
        let (record, bridged, spans) = measure_with_spans(&series, 0.01, &factors, &opts, &mut Vec::new());
        assert!(bridged.is_empty());
        let variances = |points: &[AllanPoint]| points.iter().map(|p| (p.m, p.tau, p.terms)).collect::<Vec<_>>();
        // Measured in one pass, the record and each span are their own measurements, up to the
        // order of the additions.
        let close = |got: &[AllanPoint], want: &[AllanPoint]| {
            assert_eq!(variances(got), variances(want));
            for (g, w) in got.iter().zip(want) {
                assert!((g.avar / w.avar - 1.0).abs() < 1e-9, "m = {}: {} vs {}", g.m, g.avar, w.avar);
            }
        };
        close(&record, &oavar_rate(&series, 0.01, &factors));
        assert_eq!(spans.len(), 7);
        for (i, s) in spans.iter().enumerate() {
            let start = i as f64 * 512.0 * 0.01;
            assert_eq!(s.span, Span { start_s: start, end_s: start + 1024.0 * 0.01 });
            // Each span's Allan variance is that of its own 1024 samples, up to m = 1024/3.
            close(&s.points, &oavar_rate(&series[i * 512..i * 512 + 1024], 0.01, &opts.grid.factors(341)));
        }
        // Fewer than two spans' worth: no span check at all.
        assert!(measure_with_spans(&series[..2047], 0.01, &factors, &opts, &mut Vec::new()).2.is_empty());
    }

    #[test]
    fn check_span_scores_the_whole_record_model_on_the_span() {
        // A model of one white term, σ² = 1 at every τ of the fit; the span measures 1.1.
        let fit_points: Vec<FitPoint> = [1usize, 2, 4]
            .iter()
            .map(|&m| FitPoint { m, tau: m as f64, measured: 1.0, model: 1.0, edf: 100.0, z: 0.0, bridged: false })
            .collect();
        let fit = CurveFit {
            terms: vec![FittedTerm {
                effect: "white".into(),
                alias: None,
                domain: Domain::Spectral,
                params: Vec::new(),
                curve: vec![1.0; 3],
                explanation: String::new(),
            }],
            points: fit_points,
            fit_error: 0.0,
            chi2: 0.0,
            failing_tau: Vec::new(),
            n_params: 1,
            classes: vec![NoiseClass::WhiteFm],
            fourth_cumulant: 0.0,
        };
        let point = |m: usize, terms: usize| AllanPoint {
            m,
            tau: m as f64,
            avar: 1.1,
            terms,
            edf: 0.0,
            ci_low: 0.0,
            ci_high: 0.0,
        };
        let measure = SpanMeasure {
            span: Span { start_s: 0.0, end_s: 10.0 },
            points: vec![
                point(1, 4000),
                point(2, 3000),
                point(4, 10), // EDF below MIN_SPAN_EDF: left out
                point(8, 4000), // no τ of the fit: left out
            ],
        };
        let (checked, z) = check_span(&measure, &fit);
        // z = (1.1 − 1)/(1·√(2/edf)) = 0.1·√(edf/2), edf that of white FM for the span's length.
        let want: Vec<f64> = [(1usize, 4000usize), (2, 3000)]
            .iter()
            .map(|&(m, terms)| 0.1 * (edf_oavar(NoiseClass::WhiteFm, terms + 2 * m, m) / 2.0).sqrt())
            .collect();
        assert_eq!(z.len(), 2);
        for (got, want) in z.iter().zip(&want) {
            assert!((got / want - 1.0).abs() < 1e-9, "{got} vs {want}");
        }
        assert_eq!(checked.span, measure.span);
        assert_eq!(checked.fit_error, rms(&z));
        // Louder than the model: a positive mean z; the same span measured quieter, a negative one.
        assert!((checked.mean_z - (want[0] + want[1]) / 2.0).abs() < 1e-9 * checked.mean_z, "{}", checked.mean_z);
        let quieter = SpanMeasure {
            points: measure.points.iter().map(|p| AllanPoint { avar: 0.9, ..*p }).collect(),
            ..measure
        };
        let quieter = check_span(&quieter, &fit).0;
        assert!((quieter.mean_z + checked.mean_z).abs() < 1e-9 * checked.mean_z);
        // The worst point is the one of largest |z| among those counted (the larger EDF, with the
        // same ratio), with its ratio; the points left out (m = 4, 8) do not count.
        let worst_tau = if want[0] >= want[1] { 1.0 } else { 2.0 };
        assert_eq!((checked.worst_tau, checked.worst_ratio), (worst_tau, 1.1));
        assert_eq!((quieter.worst_tau, quieter.worst_ratio), (worst_tau, 0.9));
        let uneven = SpanMeasure {
            points: vec![AllanPoint { avar: 1.21, ..point(1, 4000) }, point(2, 3000), AllanPoint { avar: 50.0, ..point(4, 10) }],
            ..measure
        };
        assert_eq!((check_span(&uneven, &fit).0.worst_tau, check_span(&uneven, &fit).0.worst_ratio), (1.0, 1.21));
        let empty = SpanMeasure { points: vec![point(4, 10)], ..measure };
        assert_eq!((check_span(&empty, &fit).0.worst_tau, check_span(&empty, &fit).0.worst_ratio), (0.0, 1.0));
    }
}

//! The text and CSV of `fdavar fit` / `fdavar diagnose`: one fitted parameter, one axis's table and
//! suggestions, and the Allan curve with the model and z per τ.
//!
//! Every number goes out with its unit, and the unit comes from one place: the parameter's own
//! (its schema unit on its axis, [`ParamValue::unit`]), the same string the JSON
//! ([`crate::model::output::param_json`]) and the node's `Coefficient` message carry. Numbers are
//! printed to significant digits ([`sig`]), so a time reads `30 s`, not `3.0000e1`.
use std::io::Write;

use crate::model::diagnose::Diagnosis;
use crate::model::fit::{FittedModel, ParamValue, SpanCheck, FAILING_Z};
use crate::model::output::{measured_points, model_curves};
use crate::report::table::{sig, Table};
use crate::report::units::{Coefficient, Sensor};

/// Significant digits of a value in the text.
const VALUE_DIGITS: usize = 5;
/// Significant digits of a σ or a bound in the text.
const SIGMA_DIGITS: usize = 3;

/// `x` to `digits` significant digits ([`sig`]) without the trailing zeros of plain notation:
/// `30`, not `30.000`.
fn short(x: f64, digits: usize) -> String {
    let s = sig(x, digits);
    if s.contains('.') && !s.contains('e') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// The unit after a number: ` unit`, or nothing for a dimensionless one (`1`).
fn unit_suffix(unit: &str) -> String {
    if unit.is_empty() || unit == "1" {
        String::new()
    } else {
        format!(" {unit}")
    }
}

/// A number and its unit as the text prints them (`30 s`, `1.6972e-4 rad/s/sqrt(Hz)`).
fn with_unit(x: f64, digits: usize, unit: &str) -> String {
    format!("{}{}", short(x, digits), unit_suffix(unit))
}

/// One fitted parameter as the text prints it: value ± σ and unit, the axis name of an
/// axis-valued parameter, or "not resolved" with its upper bound ([`ParamValue::upper_bound`]).
///
/// ```
/// use fdavar::model::fit::ParamValue;
/// use fdavar::report::fit::param_text;
/// let p = |name: &str, unit: &str, value, sigma| ParamValue { name: name.into(), unit: unit.into(), value, sigma };
/// assert_eq!(param_text(&p("start_s", "s", 30.0, None)), "30 s");
/// assert_eq!(param_text(&p("n", "rad/s/sqrt(Hz)", 1.6972e-4, Some(1.054e-5))), "1.6972e-4 ± 1.05e-5 rad/s/sqrt(Hz)");
/// assert_eq!(param_text(&p("b", "rad/s", 0.0, Some(3.346e-4))), "not resolved (< 6.69e-4 rad/s, 2σ)");
/// assert_eq!(param_text(&p("source", "axis", 0.0, None)), "accel_x");
/// ```
pub fn param_text(p: &ParamValue) -> String {
    if let Some(axis) = p.axis() {
        return axis.name().to_string();
    }
    if let Some(bound) = p.upper_bound() {
        return format!(
            "not resolved (< {}, {}σ)",
            with_unit(bound, SIGMA_DIGITS, &p.unit),
            ParamValue::BOUND_SIGMAS
        );
    }
    let sigma = p.sigma.map_or(String::new(), |s| format!(" ± {}", short(s, SIGMA_DIGITS)));
    format!("{}{sigma}{}", short(p.value, VALUE_DIGITS), unit_suffix(&p.unit))
}

/// The seed's display unit of a coefficient (N, B, K, Q, R) after its SI text, e.g.
/// `= 0.5835 °/√h`; the bound of an unresolved one (`< 138 °/h`); empty for other parameters.
fn display_text(effect: &str, p: &ParamValue, first: bool, axis: &str) -> String {
    let (Some(c), Some(s), true) = (Coefficient::from_effect(effect), Sensor::of_axis(axis), first)
    else {
        return String::new();
    };
    match p.upper_bound() {
        Some(bound) => format!("  = < {}", with_unit(c.to_display(s, bound), 4, c.display_unit(s))),
        None => format!("  = {}", with_unit(c.to_display(s, p.value), 4, c.display_unit(s))),
    }
}

/// Writes the readable table of one fitted axis: model and fit_error, each parameter with its
/// unit, where the model fails in τ and in time, and the located events.
///
/// `failing` is the misfit ([`FittedModel::misfit`]) above which the model is reported as
/// failing; when it fails but no τ fails, the line says that the failure is in time.
///
/// # Errors
/// Those of `w`.
pub fn write_fit(w: &mut dyn Write, f: &FittedModel, failing: f64) -> std::io::Result<()> {
    write!(w, "{}  model {}  fit_error {:.2}", f.axis, f.spec, f.fit_error)?;
    match f.span_fit_error {
        Some(spans) => writeln!(w, "  span_fit_error {spans:.2}")?,
        None => writeln!(w)?,
    }
    for t in &f.terms {
        for (i, p) in t.params.iter().enumerate() {
            writeln!(
                w,
                "  {:<18} {:<18} {}{}",
                t.effect,
                p.name,
                param_text(p),
                display_text(&t.effect, p, i == 0, f.axis.name())
            )?;
        }
    }
    if f.failing_tau.is_empty() {
        if let Some(spans) = f.span_fit_error.filter(|&s| s > failing) {
            // The whole-record curve fits; the spans do not (FittedModel::span_fit_error).
            writeln!(
                w,
                "  failing tau: none (the whole-record curve fits); the failure is in time (span_fit_error {spans:.2}): {}",
                if f.failing_spans.is_empty() {
                    "the record's spans together, none alone above 3"
                } else {
                    "see the spans below"
                }
            )?;
        } else {
            writeln!(w, "  failing tau: none")?;
        }
    } else {
        let spans: Vec<String> = f
            .failing_tau
            .iter()
            .map(|r| match r[0] == r[1] {
                // One τ of the grid.
                true => format!("{} s", short(r[0], 4)),
                false => format!("{}-{} s", short(r[0], 4), short(r[1], 4)),
            })
            .collect();
        writeln!(w, "  failing tau: {}", spans.join(", "))?;
    }
    if !f.failing_spans.is_empty() {
        let spans: Vec<String> = f
            .failing_spans
            .iter()
            .map(|s| format!("{}-{} s, {}", short(s.start_s, 4), short(s.end_s, 4), side_of(f, s)))
            .collect();
        writeln!(
            w,
            "  failing in time: {} (span_fit_error {:.2})",
            spans.join("; "),
            f.span_fit_error.unwrap_or(f64::NAN)
        )?;
    }
    if f.rate_excess_kurtosis > 0.0 {
        writeln!(
            w,
            "  heavy-tailed rate noise: excess kurtosis {:.3} (isolated spikes: glitches, knocks); every interval and z is widened for it",
            f.rate_excess_kurtosis
        )?;
    }
    for e in &f.events {
        // Event parameters are times (`*_s`, seconds) or a noise factor (dimensionless).
        let ps: Vec<String> = e
            .params
            .iter()
            .map(|(k, v)| format!("{k}={}", with_unit(*v, VALUE_DIGITS, if k.ends_with("_s") { "s" } else { "" })))
            .collect();
        writeln!(w, "  event: {} {}", e.effect, ps.join(" "))?;
    }
    Ok(())
}

/// Writes the suggestions of a diagnosis, best first, each parameter with its unit
/// ([`param_text`]), the fit_error with it and its sentence; `suggestions: none` when there is none.
///
/// # Errors
/// Those of `w`.
pub fn write_suggestions(w: &mut dyn Write, d: &Diagnosis) -> std::io::Result<()> {
    if d.suggestions.is_empty() {
        writeln!(w, "  suggestions: none")?;
    }
    for (i, s) in d.suggestions.iter().enumerate() {
        let ps: Vec<String> =
            s.params.iter().map(|p| format!("{} = {}", p.name, param_text(p))).collect();
        let given = if s.given.is_empty() { String::new() } else { format!(" with {}", s.given.join(" and ")) };
        // None: the record was too short to be checked on spans.
        let in_time = s.span_fit_error_after.map_or(String::new(), |spans| format!(", span_fit_error {spans:.2}"));
        writeln!(
            w,
            "  suggestion {}: add {}{given} ({}) -> fit_error {:.2}{in_time}\n    {}",
            i + 1,
            s.effect,
            ps.join(", "),
            s.fit_error_after,
            s.explanation
        )?;
    }
    Ok(())
}

/// The columns of [`allan_table`], in order.
pub const ALLAN_CSV_COLUMNS: [&str; 8] =
    ["tau_s", "m", "adev", "adev_low", "adev_high", "edf", "model_adev", "z"];

/// The Allan curve of one fitted axis, the model at the same τ and z, one row per τ
/// (`fdavar fit|diagnose --csv DIR`).
///
/// Columns ([`ALLAN_CSV_COLUMNS`]): `tau_s` τ \[s\]; `m` the averaging factor τ/τ0; `adev` the
/// measured overlapping Allan deviation σ(τ), `adev_low`/`adev_high` its 68.3 % interval under
/// `edf`, `model_adev` the model's σ(τ), all in the axis unit (rad/s or m/s²); `edf` the equivalent
/// degrees of freedom under the model's noise mix; `z` the residual (dimensionless). Numbers are
/// written in full (Rust's shortest round-trip form), so they read back exactly.
///
/// # Formula
/// ```text
/// adev = √σ²_meas    adev_low, adev_high = √ci    model_adev = √max(σ²_model, 0)
/// z = (σ²_meas − σ²_model) / (σ²_model·√(2/edf))
/// ```
/// where σ²_meas, σ²_model and ci are the fit's [`crate::model::fit::FitPoint`] fields
/// (`measured`, `model`, `ci()`); they are the figure's values
/// ([`crate::model::output::allan_figure`]).
pub fn allan_table(f: &FittedModel) -> Table {
    let mut t = Table::new(ALLAN_CSV_COLUMNS);
    let measured = measured_points(f);
    let model = model_curves(f);
    for ((p, m), (fp, (_, z))) in measured.iter().zip(&model.total).zip(f.points.iter().zip(&model.z)) {
        t.push([
            p.tau.to_string(),
            fp.m.to_string(),
            p.dev.to_string(),
            p.dev_low.to_string(),
            p.dev_high.to_string(),
            fp.edf.to_string(),
            m.1.to_string(),
            z.to_string(),
        ]);
    }
    t
}

/// The columns of [`spans_table`], in order.
pub const SPANS_CSV_COLUMNS: [&str; 6] = ["start_s", "end_s", "fit_error", "mean_z", "worst_tau_s", "worst_ratio"];

/// The model checked on each span of the record, one row per span in time order
/// (`fdavar fit|diagnose --csv DIR`, `spans_<axis>.csv`): the numbers of the figure's span panel.
///
/// Columns ([`SPANS_CSV_COLUMNS`]): `start_s`, `end_s` the span, seconds from the first sample;
/// `fit_error` the RMS of z over the span's own τ grid against the whole-record model; `mean_z`
/// their mean (positive: the span louder than the model); `worst_tau_s` and `worst_ratio` the τ of
/// the span's point of largest |z| and its measured / model Allan variance
/// ([`SpanCheck::worst_ratio`]). Numbers in full, as [`allan_table`].
/// No rows when the record is too short to be cut into spans.
pub fn spans_table(f: &FittedModel) -> Table {
    let mut t = Table::new(SPANS_CSV_COLUMNS);
    for c in &f.spans {
        t.push([c.span.start_s, c.span.end_s, c.fit_error, c.mean_z, c.worst_tau, c.worst_ratio].map(|v| v.to_string()));
    }
    t
}

/// Which side of the model the failing spans inside `interval` lie on, by the sign of their mean z
/// (`SpanCheck::mean_z`): the noise there louder than the model, quieter, or both in turn (a model
/// that averages two levels fits neither); and the largest of its failing spans' worst points
/// (each span's point of largest |z|, `SpanCheck::worst_ratio`), as a change of Allan variance at
/// its τ: "louder than the model, worst ×3.5 at τ 20 s".
fn side_of(f: &FittedModel, interval: &crate::model::fit::Span) -> String {
    let inside: Vec<&SpanCheck> = f
        .spans
        .iter()
        .filter(|c| c.fit_error > FAILING_Z && c.span.start_s >= interval.start_s && c.span.end_s <= interval.end_s)
        .collect();
    let (louder, quieter) = inside.iter().fold((false, false), |(l, q), c| (l || c.mean_z >= 0.0, q || c.mean_z < 0.0));
    let side = match (louder, quieter) {
        (true, false) => "louder than the model",
        (false, true) => "quieter than the model",
        _ => "louder and quieter in turn",
    };
    // The failing span whose worst point departs most, by its ratio in log: ×2 and ×0.5 alike.
    let worst = inside.iter().max_by(|a, b| a.worst_ratio.ln().abs().total_cmp(&b.worst_ratio.ln().abs()));
    match worst {
        Some(c) => format!("{side}, worst {} at τ {} s", change_text(c.worst_ratio), short(c.worst_tau, 3)),
        None => side.to_string(),
    }
}

/// A ratio of Allan variances as a change: `+4.5 %`, `-6.1 %`, or a factor (`×12`, `×0.31`)
/// beyond a doubling or a halving.
fn change_text(ratio: f64) -> String {
    if (0.5..2.0).contains(&ratio) {
        format!("{:+.1} %", 100.0 * (ratio - 1.0))
    } else {
        format!("×{}", short(ratio, 2))
    }
}

//! The Allan deviation figure: measured σ(τ) with its confidence band, the fitted model and each of
//! its terms, a residual panel of z with the failing τ ranges shaded, and (when the fit checked the
//! model on spans of the record) a panel of each span's fit error over time.
use serde::{Deserialize, Serialize};

use super::*;

const FIGURE: &str = "allan";

/// The level beyond which a z, or a span's fit error, fails: |z| > 3 (docs/design.md §5).
const FAILING: f64 = 3.0;

/// One measured Allan deviation with its confidence interval.
///
/// Plain data so that the figure does not depend on the estimator's types.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeasuredPoint {
    /// Averaging time τ \[s\].
    pub tau: f64,
    /// Allan deviation σ(τ), in the axis unit (rad/s or m/s²).
    pub dev: f64,
    /// Lower end of the confidence interval of σ (same unit).
    pub dev_low: f64,
    /// Upper end of the confidence interval of σ (same unit).
    pub dev_high: f64,
    /// Measured across lost samples (`allan::oavar_rate_bridged`): drawn hollow.
    #[serde(default)]
    pub bridged: bool,
}

/// One term of a noise model (e.g. `white`) as a deviation curve σ_term(τ).
///
/// A point whose σ is exactly 0 (a term the fit set to zero) is not drawn: it has no place on a
/// log axis. The legend then marks the term "(zero)".
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Term {
    /// The effect name or alias shown in the legend (e.g. `white`, `N`).
    pub name: String,
    /// (τ \[s\], σ_term(τ)) pairs, τ increasing.
    pub curve: Vec<(f64, f64)>,
}

/// The model checked on one span of the record: the span's own Allan variance against the
/// whole-record model (the fit's time-resolved check, `crate::model::fit::SpanCheck`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpanScore {
    /// Start of the span, seconds from the first sample.
    pub start_s: f64,
    /// End of the span, seconds from the first sample.
    pub end_s: f64,
    /// RMS of z over the span's τ grid.
    pub fit_error: f64,
    /// Whether the span's Allan variance lies above the model on the whole (mean z ≥ 0): drawn
    /// above the zero line, a quieter span below it.
    #[serde(default = "louder_by_default")]
    pub louder: bool,
}

fn louder_by_default() -> bool {
    true
}

impl SpanScore {
    /// The span's fit error signed by `louder`, where the panel draws it.
    fn signed(&self) -> f64 {
        if self.louder {
            self.fit_error
        } else {
            -self.fit_error
        }
    }
}

/// A fitted model as the figures see it: its curves, residuals and error.
///
/// `z` and `failing_tau` follow the contracts of docs/design.md §5: z = (σ²_meas − σ²_model) /
/// (σ²_model·√(2/EDF)) per τ, failing τ = the maximal τ intervals where |z| > 3.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelCurves {
    /// What the model is, for titles and legends (e.g. `N + B + K`).
    pub label: String,
    /// (τ \[s\], σ_model(τ)): the total model deviation, τ increasing.
    pub total: Vec<(f64, f64)>,
    /// Each term's own curve.
    pub terms: Vec<Term>,
    /// (τ \[s\], z) residuals on the measured τ grid.
    pub z: Vec<(f64, f64)>,
    /// Maximal τ intervals \[lo, hi\] (seconds) where |z| > 3.
    pub failing_tau: Vec<(f64, f64)>,
    /// RMS of z over the τ grid (≈ 1 when the model explains the measurement): the contract's
    /// fit_error.
    pub fit_error: f64,
    /// RMS of z over the spans' τ grids pooled (the fit's `span_fit_error`: how well the model
    /// holds in time); `None` without a time-resolved check.
    #[serde(default)]
    pub span_fit_error: Option<f64>,
    /// Each span's check, in time order; empty: no time-resolved check, and no span panel.
    ///
    /// Why a panel of its own: a model can pass through every point of the whole-record curve
    /// (the noise averaged over the record) and still fail where the record is not stationary (a
    /// step, a burst, a louder half); the z panel cannot show that, the span panel shows when.
    #[serde(default)]
    pub spans: Vec<SpanScore>,
    /// Maximal time intervals \[start, end\] (seconds) covered by spans whose fit error exceeds
    /// 3, as the fit merges them (`FittedModel::failing_spans`): shaded in the span panel.
    #[serde(default)]
    pub failing_spans: Vec<(f64, f64)>,
}

/// The Allan deviation figure of one axis and one model.
///
/// Top panel: measured σ(τ) (points, confidence band), the model total (black) and each term
/// (dashed), failing τ shaded. Below: z(τ) with the |z| = 3 guide lines and the same shading;
/// then, when the model has [`ModelCurves::spans`], each span's fit error against time, spans
/// above 3 shaded. Write it with [`write_allan`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AllanFigure {
    /// Axis name (`gyro_x` … `accel_z`).
    pub axis: String,
    /// Unit of σ (e.g. `rad/s`, `m/s²`), shown in the axis title.
    pub unit: String,
    /// Figure title (e.g. the recording's name); the axis and fit error are added to it.
    pub title: String,
    /// Measured deviations with confidence intervals, τ increasing.
    pub measured: Vec<MeasuredPoint>,
    /// The fitted model.
    pub model: ModelCurves,
}

/// Before/after figure for a suggested effect: two models, each against the data it was fitted to,
/// side by side on identical axes, each column with its fit error.
///
/// Use it to show what adding a diagnosed effect changes: the shaded failing τ ranges should
/// shrink and the fit error fall from left to right. A spectral effect (a sinusoid) is fitted to
/// the same Allan curve; a time-domain effect (temperature, a bias step) is removed from the
/// samples first, so the "after" column shows the Allan deviation of what is left
/// (`after_measured`), the data its z panel judges. Write it with [`write_allan_comparison`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AllanComparison {
    /// Axis name (`gyro_x` … `accel_z`).
    pub axis: String,
    /// Unit of σ (e.g. `rad/s`), shown in the axis title.
    pub unit: String,
    /// Figure title; the axis is added to it.
    pub title: String,
    /// Measured deviations with confidence intervals, τ increasing.
    pub measured: Vec<MeasuredPoint>,
    /// The data the "after" model is fitted to when it is not `measured`: the deviations of the
    /// samples with the suggested time-domain term removed; `None`: the same as `measured`.
    #[serde(default)]
    pub after_measured: Option<Vec<MeasuredPoint>>,
    /// The model before the suggestion.
    pub before: ModelCurves,
    /// The model with the suggested effect added.
    pub after: ModelCurves,
}

/// Writes the Allan figure to `<stem>.png` and `<stem>.svg` and returns both paths.
///
/// The parent directory is created if needed.
///
/// # Errors
/// [`ReportError`] naming the field and index when an input is empty, NaN/infinite, not positive
/// where it goes on a log axis (τ, measured σ and its band), or an interval is reversed;
/// [`ReportError::Draw`] when a file cannot be written.
pub fn write_allan(figure: &AllanFigure, stem: &Path) -> Result<Vec<PathBuf>, ReportError> {
    let heading = format!("model {}", figure.model.label);
    let panels = Panels::new(
        &figure.axis,
        &figure.unit,
        &figure.title,
        vec![(heading, &figure.model, &figure.measured)],
    )?;
    write_figure(&panels, stem)
}

/// Writes the before/after figure to `<stem>.png` and `<stem>.svg` and returns both paths.
///
/// # Errors
/// As [`write_allan`], for the measurement and both models.
pub fn write_allan_comparison(
    figure: &AllanComparison,
    stem: &Path,
) -> Result<Vec<PathBuf>, ReportError> {
    // The after model named by what it adds when it keeps every term of the before model: the
    // full list twice made captions too long for their columns.
    // (By the labels: a time-domain term has no curve among the terms.)
    let names = |m: &ModelCurves| -> Vec<String> { m.label.split(" + ").map(str::to_string).collect() };
    let (before_names, after_names) = (names(&figure.before), names(&figure.after));
    let added: Vec<&str> =
        after_names.iter().filter(|n| !before_names.contains(n)).map(String::as_str).collect();
    let after_label = if !added.is_empty() && before_names.iter().all(|n| after_names.contains(n)) {
        format!("+ {}", added.join(" + "))
    } else {
        figure.after.label.clone()
    };
    let after: Column<'_> = match &figure.after_measured {
        Some(m) => (format!("after: {after_label}, on the data less its time-domain terms"), &figure.after, m),
        None => (format!("after: {after_label}"), &figure.after, &figure.measured),
    };
    let before = format!("before: {}", figure.before.label);
    let panels = Panels::new(
        &figure.axis,
        &figure.unit,
        &figure.title,
        vec![(before, &figure.before, &figure.measured[..]), after],
    )?;
    write_figure(&panels, stem)
}

/// Checks one model's curves; `which` prefixes field names (`before.`, `after.` or empty).
fn validate_model(which: &str, m: &ModelCurves) -> Result<(), ReportError> {
    let f = |name: &str| format!("{which}{name}");
    check_non_empty(FIGURE, &f("total"), m.total.len())?;
    check_positive(FIGURE, &f("total.tau"), m.total.iter().map(|p| p.0))?;
    let non_negative = |field: &str, values: &[(f64, f64)]| {
        check_values(
            FIGURE,
            field,
            values.iter().map(|p| p.1),
            Need::NonNegative,
            false,
        )
    };
    non_negative(&f("total.dev"), &m.total)?;
    for (i, term) in m.terms.iter().enumerate() {
        check_positive(
            FIGURE,
            &f(&format!("terms[{i}].tau")),
            term.curve.iter().map(|p| p.0),
        )?;
        non_negative(&f(&format!("terms[{i}].dev")), &term.curve)?;
    }
    check_non_empty(FIGURE, &f("z"), m.z.len())?;
    check_positive(FIGURE, &f("z.tau"), m.z.iter().map(|p| p.0))?;
    check_finite(FIGURE, &f("z.z"), m.z.iter().map(|p| p.1))?;
    check_intervals(FIGURE, &f("failing_tau"), &m.failing_tau, true)?;
    check_finite(FIGURE, &f("fit_error"), [m.fit_error])?;
    check_finite(FIGURE, &f("span_fit_error"), m.span_fit_error)?;
    let times: Vec<(f64, f64)> = m.spans.iter().map(|s| (s.start_s, s.end_s)).collect();
    check_intervals(FIGURE, &f("spans.start_s/end_s"), &times, false)?;
    let errors = m.spans.iter().map(|s| s.fit_error);
    check_values(FIGURE, &f("spans.fit_error"), errors, Need::NonNegative, false)?;
    check_intervals(FIGURE, &f("failing_spans"), &m.failing_spans, false)
}

/// One column of an Allan figure: (heading, model, the measurement it was fitted to).
type Column<'a> = (String, &'a ModelCurves, &'a [MeasuredPoint]);

/// A validated Allan figure with one column per model and shared axis ranges.
struct Panels<'a> {
    axis: &'a str,
    unit: &'a str,
    title: &'a str,
    /// (column heading, model, measurement).
    models: Vec<Column<'a>>,
    /// Term names in first-appearance order; a term keeps its colour across columns.
    term_names: Vec<String>,
    tau_range: std::ops::Range<f64>,
    dev_range: std::ops::Range<f64>,
    /// Half height of the z panel.
    z_bound: f64,
    /// Time axis of the span panels (`None`: no column has spans, no span panel).
    time_range: Option<std::ops::Range<f64>>,
    /// Height of the span panels.
    span_bound: f64,
}

impl<'a> Panels<'a> {
    fn new(
        axis: &'a str,
        unit: &'a str,
        title: &'a str,
        models: Vec<Column<'a>>,
    ) -> Result<Self, ReportError> {
        for (i, (_, _, measured)) in models.iter().enumerate() {
            // The first column's data is `measured`, a second one's `after_measured`.
            let field = if i == 0 { "measured" } else { "after_measured" };
            let f = |name: &str| format!("{field}{name}");
            check_non_empty(FIGURE, field, measured.len())?;
            check_positive(FIGURE, &f(".tau"), measured.iter().map(|p| p.tau))?;
            check_positive(FIGURE, &f(".dev"), measured.iter().map(|p| p.dev))?;
            let bands: Vec<(f64, f64)> = measured.iter().map(|p| (p.dev_low, p.dev_high)).collect();
            check_intervals(FIGURE, &f(".dev_low/dev_high"), &bands, true)?;
        }
        for (i, (_, m, _)) in models.iter().enumerate() {
            // Field names as the figure's data has them: `model`, or `before` and `after`.
            let prefix = match (models.len(), i) {
                (1, _) => "model.",
                (_, 0) => "before.",
                _ => "after.",
            };
            validate_model(prefix, m)?;
        }

        let mut term_names: Vec<String> = Vec::new();
        for (_, m, _) in &models {
            for t in &m.terms {
                if !term_names.contains(&t.name) {
                    term_names.push(t.name.clone());
                }
            }
        }
        // Validated above: every range below has at least one positive finite value.
        let all_tau = models.iter().flat_map(|(_, m, measured)| {
            measured.iter().map(|p| p.tau).chain(m.total.iter().chain(&m.z).map(|p| p.0))
        });
        let (tau_lo, tau_hi) = min_max(all_tau).unwrap_or((1.0, 10.0));
        // σ range from what must be seen: the measurement, its band and the model totals. Terms
        // that fall far below (e.g. quantization at long τ) run off the bottom of the plot.
        let all_dev = models.iter().flat_map(|(_, m, measured)| {
            measured
                .iter()
                .flat_map(|p| [p.dev_low, p.dev_high])
                .chain(m.total.iter().map(|p| p.1).filter(|&d| d > 0.0))
        });
        let (dev_lo, dev_hi) = min_max(all_dev).unwrap_or((1.0, 10.0));
        check_log_span(FIGURE, "tau", tau_lo, tau_hi)?;
        check_log_span(FIGURE, "dev", dev_lo, dev_hi)?;
        let z_max = min_max(
            models
                .iter()
                .flat_map(|(_, m, _)| m.z.iter().map(|p| p.1.abs())),
        )
        .map_or(0.0, |(_, hi)| hi);
        let spans = || models.iter().flat_map(|(_, m, _)| &m.spans);
        let time_range = match min_max(spans().flat_map(|s| [s.start_s, s.end_s])) {
            Some((lo, hi)) => {
                check_linear_span(FIGURE, "spans.start_s/end_s", lo, hi)?;
                Some(lo..hi)
            }
            None => None,
        };
        let span_max = min_max(spans().map(|s| s.fit_error)).map_or(0.0, |(_, hi)| hi);
        Ok(Panels {
            axis,
            unit,
            title,
            models,
            term_names,
            tau_range: log_range(tau_lo, tau_hi, 1.25),
            dev_range: log_range(dev_lo, dev_hi, 1.25),
            // Capped so that ±∞ can never reach the axis (z is finite, but 1.1·f64::MAX is not).
            z_bound: (z_max.min(1e300) * 1.1).max(4.0),
            time_range,
            span_bound: tick_ceiling(span_max.min(1e300) * 1.1),
        })
    }

    fn term_colour(&self, name: &str) -> RGBColor {
        let i = self.term_names.iter().position(|n| n == name).unwrap_or(0);
        TERM_COLOURS[i % TERM_COLOURS.len()]
    }

    /// Draws one column: σ(τ) panel over z(τ) panel for `model` fitted to `measured`.
    fn draw_column<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        (heading, model, measured): &Column<'_>,
    ) -> Drawn {
        // τ of the measured grid, for padding shaded spans by half a grid step.
        let grid: Vec<f64> = measured.iter().map(|p| p.tau).collect();
        // The spans' error beside fit_error when the model holds worse in time than over τ.
        let in_time = match model.span_fit_error {
            Some(spans) if !model.spans.is_empty() && spans - model.fit_error > 0.005 => {
                format!(" (in time {spans:.2})")
            }
            _ => String::new(),
        };
        let caption = format!("{heading} — fit error {:.2}{in_time}", model.fit_error);
        let (w, h) = area.dim_in_pixel();
        // A long caption (a model of many terms, the spans' error) shrinks to its column
        // instead of running into the next one: about 0.55 em per character.
        let caption_size = (19.0_f64).min((w as f64 - 20.0) / (0.55 * caption.chars().count() as f64)).max(13.0);
        let (top, bottom) = area.split_vertically(h * if self.time_range.is_some() { 54 } else { 66 } / 100);
        let (bottom, span_area) = match &self.time_range {
            Some(_) => {
                let (z_area, span_area) = bottom.split_vertically(bottom.dim_in_pixel().1 / 2);
                (z_area, Some(span_area))
            }
            None => (bottom, None),
        };
        let spans: Vec<(f64, f64)> = model
            .failing_tau
            .iter()
            .map(|&(lo, hi)| pad_span(lo, hi, &grid))
            .collect();

        // --- σ(τ) panel
        let mut chart = ChartBuilder::on(&top)
            .caption(caption, text(caption_size as u32))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(
                self.tau_range.clone().log_scale(),
                self.dev_range.clone().log_scale(),
            )?;
        mesh_look(&mut chart.configure_mesh())
            .x_desc("τ [s]")
            .y_desc(format!("Allan deviation σ(τ) [{}]", self.unit))
            .x_labels(40)
            .y_labels(40)
            .x_label_formatter(&decade_label)
            .y_label_formatter(&decade_label)
            .draw()?;
        let (y0, y1) = (self.dev_range.start, self.dev_range.end);
        chart.draw_series(
            spans
                .iter()
                .map(|&(lo, hi)| Rectangle::new([(lo, y0), (hi, y1)], SHADE.filled())),
        )?;
        // Confidence band as one polygon: upper edge left→right, lower edge right→left.
        let band: Vec<(f64, f64)> = measured
            .iter()
            .map(|p| (p.tau, p.dev_high))
            .chain(measured.iter().rev().map(|p| (p.tau, p.dev_low)))
            .collect();
        chart.draw_series(std::iter::once(Polygon::new(band, BAND.filled())))?;
        for term in &model.terms {
            let colour = self.term_colour(&term.name);
            for segment in clipped_runs(&term.curve, self.dev_range.start, self.dev_range.end) {
                chart.draw_series(DashedLineSeries::new(segment, 8, 5, colour.stroke_width(2)))?;
            }
        }
        for segment in clipped_runs(&model.total, self.dev_range.start, self.dev_range.end) {
            chart.draw_series(LineSeries::new(segment, BLACK.stroke_width(3)))?;
        }
        chart.draw_series(LineSeries::new(
            measured.iter().map(|p| (p.tau, p.dev)),
            MEASURED.stroke_width(1),
        ))?;
        chart.draw_series(measured.iter().map(|p| {
            let style = if p.bridged { MEASURED.stroke_width(2) } else { MEASURED.filled() };
            Circle::new((p.tau, p.dev), 3, style)
        }))?;

        // --- z(τ) panel, on a symmetric log scale so |z| = 3 stays readable next to |z| = 100.
        let b = symlog(self.z_bound);
        let mut zchart = ChartBuilder::on(&bottom)
            .margin(8)
            .x_label_area_size(42)
            .y_label_area_size(70)
            .build_cartesian_2d(self.tau_range.clone().log_scale(), -b..b)?;
        mesh_look(&mut zchart.configure_mesh())
            .x_desc("τ [s]")
            .y_desc("z (symmetric log scale)")
            .x_labels(40)
            .y_labels(0)
            .x_label_formatter(&decade_label)
            .draw()?;
        zchart.draw_series(
            spans
                .iter()
                .map(|&(lo, hi)| Rectangle::new([(lo, -b), (hi, b)], SHADE.filled())),
        )?;
        let (t0, t1) = (self.tau_range.start, self.tau_range.end);
        let ticks = z_ticks(self.z_bound);
        zchart.draw_series(
            ticks
                .iter()
                .map(|&t| PathElement::new(vec![(t0, t), (t1, t)], GRID.stroke_width(1))),
        )?;
        let labels: Vec<((i32, i32), String)> = ticks
            .iter()
            .map(|&t| {
                (
                    zchart.backend_coord(&(t0, t)),
                    plain_label(&symlog_inverse(t).round()),
                )
            })
            .collect();
        draw_ticks(&bottom, &labels, false)?;
        zchart.draw_series(LineSeries::new(
            [(t0, 0.0), (t1, 0.0)],
            BLACK.stroke_width(1),
        ))?;
        for level in [-FAILING, FAILING] {
            zchart.draw_series(DashedLineSeries::new(
                [(t0, symlog(level)), (t1, symlog(level))],
                8,
                5,
                ALERT.stroke_width(2),
            ))?;
        }
        zchart.draw_series(LineSeries::new(
            model.z.iter().map(|&(tau, z)| (tau, symlog(z))),
            RGBColor(90, 90, 90).stroke_width(1),
        ))?;
        zchart.draw_series(model.z.iter().map(|&(tau, z)| {
            let colour = if z.abs() > FAILING {
                ALERT
            } else {
                RGBColor(60, 60, 60)
            };
            Circle::new((tau, symlog(z)), 3, colour.filled())
        }))?;
        match (span_area, &self.time_range) {
            (Some(area), Some(times)) if !model.spans.is_empty() => self.draw_spans(&area, times, model),
            _ => Ok(()),
        }
    }

    /// The span panel: each span's fit error (the RMS of its z) as a segment over the span's time,
    /// above the zero line for a span louder than the model and below it for a quieter one, on
    /// the z panel's symmetric log scale; spans above 3 red, the model's failing spans shaded.
    fn draw_spans<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        times: &std::ops::Range<f64>,
        model: &ModelCurves,
    ) -> Drawn {
        let spans = &model.spans;
        let b = symlog(self.span_bound);
        let mut chart = ChartBuilder::on(area)
            .margin(8)
            .x_label_area_size(42)
            .y_label_area_size(70)
            .build_cartesian_2d(times.clone(), -b..b)?;
        mesh_look(&mut chart.configure_mesh())
            .x_desc("time of the span [s], from the first sample")
            .y_desc("span fit error (− quieter)")
            .x_labels(10)
            .y_labels(0)
            .x_label_formatter(&plain_label)
            .draw()?;
        let shaded = model.failing_spans.iter();
        chart.draw_series(shaded.map(|&(lo, hi)| Rectangle::new([(lo, -b), (hi, b)], SHADE.filled())))?;
        let (t0, t1) = (times.start, times.end);
        let ticks = z_ticks(self.span_bound);
        chart.draw_series(ticks.iter().map(|&t| PathElement::new(vec![(t0, t), (t1, t)], GRID.stroke_width(1))))?;
        let labels: Vec<((i32, i32), String)> = ticks
            .iter()
            .map(|&t| (chart.backend_coord(&(t0, t)), plain_label(&symlog_inverse(t).round())))
            .collect();
        draw_ticks(area, &labels, false)?;
        chart.draw_series(LineSeries::new([(t0, 0.0), (t1, 0.0)], BLACK.stroke_width(1)))?;
        for level in [-FAILING, FAILING] {
            chart.draw_series(DashedLineSeries::new([(t0, symlog(level)), (t1, symlog(level))], 8, 5, ALERT.stroke_width(2)))?;
        }
        let colour = |s: &SpanScore| if s.fit_error > FAILING { ALERT } else { RGBColor(60, 60, 60) };
        chart.draw_series(spans.iter().map(|s| {
            let y = symlog(s.signed());
            PathElement::new(vec![(s.start_s, y), (s.end_s, y)], colour(s).stroke_width(2))
        }))?;
        chart.draw_series(spans.iter().map(|s| {
            Circle::new(((s.start_s + s.end_s) / 2.0, symlog(s.signed())), 3, colour(s).filled())
        }))?;
        Ok(())
    }

    fn legend(&self) -> Vec<(LegendMark, String)> {
        let mut entries = vec![
            (LegendMark::Points(MEASURED), "measured σ(τ)".to_string()),
            (LegendMark::Fill(BAND), "confidence interval".to_string()),
            (LegendMark::Line(BLACK, 3), "model total".to_string()),
        ];
        if self.models.iter().any(|(_, _, measured)| measured.iter().any(|p| p.bridged)) {
            entries.insert(1, (LegendMark::Hollow(MEASURED), "bridged over lost samples".to_string()));
        }
        for name in &self.term_names {
            let zero = self.models.iter().all(|(_, m, _)| {
                m.terms
                    .iter()
                    .filter(|t| &t.name == name)
                    .all(|t| t.curve.iter().all(|p| p.1 == 0.0))
            });
            let label = if zero {
                format!("{name} (zero)")
            } else {
                name.clone()
            };
            entries.push((LegendMark::Dashed(self.term_colour(name)), label));
        }
        entries.push((LegendMark::Fill(SHADE), "failing τ (|z| > 3)".to_string()));
        entries.push((LegendMark::Dashed(ALERT), "|z| = 3".to_string()));
        if self.time_range.is_some() {
            entries.push((LegendMark::Line(RGBColor(60, 60, 60), 2), "fit error of a span".to_string()));
            entries.push((LegendMark::Fill(SHADE), "failing span (> 3)".to_string()));
        }
        entries
    }
}

impl Figure for Panels<'_> {
    fn size(&self) -> (u32, u32) {
        let height = if self.time_range.is_some() { 1150 } else { 900 };
        (250 + 950 * self.models.len() as u32, height)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Drawn {
        let (w, _) = root.dim_in_pixel();
        let heading = if self.title.is_empty() {
            format!("Allan deviation — {}", self.axis)
        } else {
            format!("{} — {}", self.title, self.axis)
        };
        let body = draw_heading(root, heading)?;
        let (plots, legend) = body.split_horizontally(w - 250);
        let columns = plots.split_evenly((1, self.models.len()));
        for (area, column) in columns.iter().zip(&self.models) {
            self.draw_column(area, column)?;
        }
        draw_legend(&legend, &self.legend(), 60)
    }
}

/// Splits a curve into the runs that lie inside `lo..=hi` on a log–log plot.
///
/// Zeros (absent terms) break the line instead of dragging it to −∞; a segment that leaves the
/// range is cut where it crosses the edge (interpolated in log–log, where the curves are nearly
/// straight), so a term that falls below the plot ends at the axis instead of running along it.
fn clipped_runs(curve: &[(f64, f64)], lo: f64, hi: f64) -> Vec<Vec<(f64, f64)>> {
    let (llo, lhi) = (lo.ln(), hi.ln());
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut run: Vec<(f64, f64)> = Vec::new();
    let mut flush = |run: &mut Vec<(f64, f64)>| {
        if run.len() > 1 {
            runs.push(std::mem::take(run));
        } else {
            run.clear();
        }
    };
    for w in curve.windows(2) {
        let ((t0, d0), (t1, d1)) = (w[0], w[1]);
        if d0 <= 0.0 || d1 <= 0.0 {
            flush(&mut run);
            continue;
        }
        let (x0, y0, x1, y1) = (t0.ln(), d0.ln(), t1.ln(), d1.ln());
        // Parameter range [a, b] of the segment inside llo ≤ y ≤ lhi.
        let (mut a, mut b) = (0.0f64, 1.0f64);
        let dy = y1 - y0;
        if dy == 0.0 {
            if y0 < llo || y0 > lhi {
                flush(&mut run);
                continue;
            }
        } else {
            let (ta, tb) = ((llo - y0) / dy, (lhi - y0) / dy);
            a = a.max(ta.min(tb));
            b = b.min(ta.max(tb));
            if a > b {
                flush(&mut run);
                continue;
            }
        }
        let at = |u: f64| ((x0 + u * (x1 - x0)).exp(), (y0 + u * dy).exp());
        if a > 0.0 {
            flush(&mut run);
        }
        if run.is_empty() {
            run.push(at(a));
        }
        run.push(at(b));
        if b < 1.0 {
            flush(&mut run);
        }
    }
    flush(&mut run);
    runs
}

/// The symmetric log transform of the z axis: linear near 0, logarithmic for large |z|.
///
/// # Formula
/// ```text
/// s(z) = sign(z) · log10(1 + |z|)
/// ```
fn symlog(z: f64) -> f64 {
    z.signum() * z.abs().ln_1p() / std::f64::consts::LN_10
}

/// The inverse of [`symlog`].
fn symlog_inverse(s: f64) -> f64 {
    s.signum() * (10f64.powf(s.abs()) - 1.0)
}

/// Tick positions (in symlog units) for a z axis reaching ±`bound`: 0, ±3, ±10, ±30, ±100, …
/// (±1 would crowd 0 and ±3, the values that matter).
fn z_ticks(bound: f64) -> Vec<f64> {
    let mut ticks = vec![0.0];
    let mut decade = 1.0;
    while decade <= bound {
        for v in [decade, 3.0 * decade] {
            if v > 1.0 && v <= bound {
                ticks.extend([symlog(v), symlog(-v)]);
            }
        }
        decade *= 10.0;
    }
    ticks.sort_by(f64::total_cmp);
    ticks
}

/// The smallest of 4, 10, 30, 100, 300, … that is at least `v`: a panel height whose top tick
/// ([`z_ticks`]) reaches its largest value, so that the values near the top can be read.
fn tick_ceiling(v: f64) -> f64 {
    if v <= 4.0 {
        return 4.0;
    }
    let mut decade = 10.0;
    while decade < 1e300 {
        if let Some(bound) = [decade, 3.0 * decade].into_iter().find(|&b| b >= v) {
            return bound;
        }
        decade *= 10.0;
    }
    // Beyond the last decade a double holds: the value itself.
    v
}

/// Widens a failing span \[lo, hi\] by half a grid step on each side (geometric midpoints to the
/// neighbouring τ of `grid`), so a single failing τ still shows as a band.
fn pad_span(lo: f64, hi: f64, grid: &[f64]) -> (f64, f64) {
    // Ratio of neighbouring τ; 10^(1/10) (the default grid density) when the grid cannot tell.
    let step = grid
        .windows(2)
        .filter(|w| w[0] > 0.0 && w[1] > w[0])
        .map(|w| w[1] / w[0])
        .fold(f64::INFINITY, f64::min);
    let step = if step.is_finite() {
        step
    } else {
        10f64.powf(0.1)
    };
    let below = grid
        .iter()
        .copied()
        .filter(|&t| t < lo)
        .fold(lo / step, f64::max);
    let above = grid
        .iter()
        .copied()
        .filter(|&t| t > hi)
        .fold(hi * step, f64::min);
    ((lo * below).sqrt(), (hi * above).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[(f64, f64)], b: &[(f64, f64)]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(p, q)| (p.0 - q.0).abs() < 1e-9 && (p.1 - q.1).abs() < 1e-9)
    }

    #[test]
    fn zero_values_split_runs() {
        let runs = clipped_runs(
            &[(1.0, 1.0), (2.0, 1.0), (3.0, 0.0), (4.0, 2.0), (5.0, 3.0)],
            0.1,
            10.0,
        );
        assert_eq!(runs.len(), 2, "{runs:?}");
        assert!(close(&runs[0], &[(1.0, 1.0), (2.0, 1.0)]), "{runs:?}");
        assert!(close(&runs[1], &[(4.0, 2.0), (5.0, 3.0)]), "{runs:?}");
    }

    #[test]
    fn lines_are_cut_at_the_axis() {
        // σ = 1/τ from τ = 1 to 100 leaves the range [0.1, 10] at τ = 10.
        let curve = [(1.0, 1.0), (100.0, 0.01)];
        let runs = clipped_runs(&curve, 0.1, 10.0);
        assert_eq!(runs.len(), 1);
        assert!(close(&runs[0], &[(1.0, 1.0), (10.0, 0.1)]), "{runs:?}");
        // Coming back in: out, in, out.
        let curve = [(1.0, 1e-3), (10.0, 1.0), (100.0, 1e3)];
        let runs = clipped_runs(&curve, 0.1, 10.0);
        let want = [
            (10f64.powf(2.0 / 3.0), 0.1),
            (10.0, 1.0),
            (10f64.powf(4.0 / 3.0), 10.0),
        ];
        assert_eq!(runs.len(), 1);
        assert!(close(&runs[0], &want), "{runs:?}");
        // Entirely below: nothing.
        assert!(clipped_runs(&[(1.0, 1e-5), (2.0, 1e-6)], 0.1, 10.0).is_empty());
    }

    #[test]
    fn span_panels_reach_their_next_tick() {
        let got: Vec<f64> = [0.0, 3.9, 4.0, 4.1, 9.0, 10.0, 10.5, 31.0, 250.0].map(tick_ceiling).to_vec();
        assert_eq!(got, [4.0, 4.0, 4.0, 10.0, 10.0, 10.0, 30.0, 100.0, 300.0]);
        assert!(tick_ceiling(1e300) >= 1e300 && tick_ceiling(1e300).is_finite());
    }

    #[test]
    fn symlog_round_trips_and_ticks() {
        for z in [-150.0, -3.0, 0.0, 0.5, 3.0, 1e4] {
            assert!((symlog_inverse(symlog(z)) - z).abs() < 1e-9 * z.abs().max(1.0));
        }
        let labels: Vec<f64> = z_ticks(40.0)
            .into_iter()
            .map(|t| symlog_inverse(t).round())
            .collect();
        assert_eq!(labels, [-30.0, -10.0, -3.0, 0.0, 3.0, 10.0, 30.0]);
    }

    #[test]
    fn span_padding_reaches_half_way_to_neighbours() {
        let grid = [1.0, 2.0, 4.0, 8.0];
        let (lo, hi) = pad_span(2.0, 4.0, &grid);
        assert!((lo - 2f64.sqrt()).abs() < 1e-12);
        assert!((hi - 32f64.sqrt()).abs() < 1e-12);
        // At the grid's end the smallest step ratio stands in for the missing neighbour.
        let (lo, hi) = pad_span(8.0, 8.0, &grid);
        assert!((lo - 32f64.sqrt()).abs() < 1e-12);
        assert!((hi - 128f64.sqrt()).abs() < 1e-12);
    }
}

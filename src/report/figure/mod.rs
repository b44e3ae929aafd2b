//! Figures: each writer draws one figure twice, to `<stem>.png` and `<stem>.svg`.
//!
//! The figures are built for one question each — *where does the model fail, and what does the
//! suggested effect change?* — so they share a few habits: log–log axes labelled at every decade
//! (10ⁿ), units in every axis title, legends in their own strip beside the plot (never over data),
//! failing τ ranges and DAVAR events shaded in a light red that lets the data show through, and
//! |z| = 3 guide lines on residual panels.
//!
//! Inputs are validated before anything is drawn: NaN, infinities, non-positive values on log
//! axes, reversed intervals and empty inputs are [`ReportError`]s naming the field and index, never
//! a panic and never a silently blank plot.
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::ReportError;

mod allan;
mod surface;
mod window;

pub use allan::{
    write_allan, write_allan_comparison, AllanComparison, AllanFigure, MeasuredPoint, ModelCurves, SpanScore,
    Term,
};
pub use surface::{write_davar_surface, DavarSurface, SURFACE_MAX_COLUMNS};
pub use window::{write_window_trace, WindowTrace};

/// DejaVu Sans (Debian fonts-dejavu-core 2.37), bundled so no system font is needed.
static FONT_BYTES: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

/// The font family name the figures use; registered once with the bundled font.
const FONT: &str = "sans-serif";

/// Registers the bundled font with plotters as `sans-serif`, once per process: every figure
/// calls it, and so can a program drawing its own plots (examples/diagnosis_power.rs), which
/// would otherwise need a system font.
///
/// # Errors
/// [`ReportError::Font`] when plotters rejects the font.
pub fn ensure_font() -> Result<(), ReportError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(ReportError::Font)
    }
}

/// A drawing failure inside a figure, before the file path is attached.
struct DrawFailed(String);

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for DrawFailed {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        DrawFailed(e.to_string())
    }
}

/// Result of drawing a figure onto a backend.
type Drawn = Result<(), DrawFailed>;

/// A validated figure that can draw itself onto any plotters backend.
trait Figure {
    /// Pixel size of the PNG (and the SVG's nominal size).
    fn size(&self) -> (u32, u32);
    /// Draws the whole figure onto `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Drawn;
}

/// `<stem>.<ext>`, keeping any dots already in the stem (`gyro_x.allan` → `gyro_x.allan.png`).
fn with_suffix(stem: &Path, ext: &str) -> PathBuf {
    let mut s = stem.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

/// Writes `figure` to `<stem>.png` and `<stem>.svg`, creating the parent directory.
fn write_figure<F: Figure>(figure: &F, stem: &Path) -> Result<Vec<PathBuf>, ReportError> {
    ensure_font()?;
    if let Some(dir) = stem.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| ReportError::CreateDir {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    let size = figure.size();
    let png = with_suffix(stem, "png");
    let svg = with_suffix(stem, "svg");
    let failed = |path: &Path| {
        let path = path.to_path_buf();
        move |DrawFailed(message)| ReportError::Draw { path, message }
    };
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        figure
            .draw(&root)
            .and_then(|()| Ok(root.present()?))
            .map_err(failed(&png))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        figure
            .draw(&root)
            .and_then(|()| Ok(root.present()?))
            .map_err(failed(&svg))?;
    }
    Ok(vec![png, svg])
}

// ---------------------------------------------------------------------------------------------
// Validation of plain input data.

/// What each value of a field must be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Need {
    /// Any finite number.
    Finite,
    /// Finite and ≥ 0 (a model term may be exactly 0: it is then not drawn).
    NonNegative,
    /// Finite and > 0 (it goes on a log axis).
    Positive,
}

/// Checks every value of a field against `need`; with `nan_is_gap`, NaN means "no value" and
/// passes. The error names `field` and the index of the first bad value.
fn check_values(
    figure: &'static str,
    field: &str,
    values: impl IntoIterator<Item = f64>,
    need: Need,
    nan_is_gap: bool,
) -> Result<(), ReportError> {
    for (index, value) in values.into_iter().enumerate() {
        let field = || field.to_string();
        if value.is_nan() && nan_is_gap {
            continue;
        }
        if !value.is_finite() {
            return Err(ReportError::NotFinite {
                figure,
                field: field(),
                index,
                value,
            });
        }
        let too_small = match need {
            Need::Finite => false,
            Need::NonNegative => value < 0.0,
            Need::Positive => value <= 0.0,
        };
        if too_small {
            return Err(ReportError::NotPositive {
                figure,
                field: field(),
                index,
                value,
            });
        }
    }
    Ok(())
}

/// Checks that `values` are all finite; `field` names them in the error.
fn check_finite(
    figure: &'static str,
    field: &str,
    values: impl IntoIterator<Item = f64>,
) -> Result<(), ReportError> {
    check_values(figure, field, values, Need::Finite, false)
}

/// Checks that `values` are all finite and > 0 (they go on a log axis).
fn check_positive(
    figure: &'static str,
    field: &str,
    values: impl IntoIterator<Item = f64>,
) -> Result<(), ReportError> {
    check_values(figure, field, values, Need::Positive, false)
}

/// Checks that `values` are finite and strictly increasing.
fn check_increasing(figure: &'static str, field: &str, values: &[f64]) -> Result<(), ReportError> {
    check_finite(figure, field, values.iter().copied())?;
    for (index, w) in values.windows(2).enumerate() {
        if w[1] <= w[0] {
            return Err(ReportError::NotIncreasing {
                figure,
                field: field.to_string(),
                index: index + 1,
                previous: w[0],
                value: w[1],
            });
        }
    }
    Ok(())
}

/// Checks that a field is not empty.
fn check_non_empty(figure: &'static str, field: &str, len: usize) -> Result<(), ReportError> {
    if len == 0 {
        return Err(ReportError::Empty {
            figure,
            field: field.to_string(),
        });
    }
    Ok(())
}

/// Checks that `field` has one entry per `per`.
fn check_len(
    figure: &'static str,
    field: &str,
    got: usize,
    per: &'static str,
    expected: usize,
) -> Result<(), ReportError> {
    if got != expected {
        return Err(ReportError::LengthMismatch {
            figure,
            field: field.to_string(),
            per,
            expected,
            got,
        });
    }
    Ok(())
}

/// Checks that each interval is finite with `low ≤ high`; `positive` also requires `low > 0`.
fn check_intervals(
    figure: &'static str,
    field: &str,
    intervals: &[(f64, f64)],
    positive: bool,
) -> Result<(), ReportError> {
    let ends = intervals.iter().flat_map(|&(lo, hi)| [lo, hi]);
    if positive {
        check_positive(figure, field, ends)?;
    } else {
        check_finite(figure, field, ends)?;
    }
    for (index, &(low, high)) in intervals.iter().enumerate() {
        if low > high {
            return Err(ReportError::Reversed {
                figure,
                field: field.to_string(),
                index,
                low,
                high,
            });
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Shared drawing habits.

/// Light red for failing τ ranges and DAVAR events: visible, data still readable through it.
const SHADE: RGBAColor = RGBAColor(230, 40, 40, 0.16);
/// Red of the |z| = 3 guide lines and of shade outlines in legends.
const ALERT: RGBColor = RGBColor(200, 30, 30);
/// Measured data.
const MEASURED: RGBColor = RGBColor(31, 92, 170);
/// The measured confidence band.
const BAND: RGBAColor = RGBAColor(31, 92, 170, 0.22);
/// Light grid lines.
const GRID: RGBColor = RGBColor(228, 228, 228);

/// Colours of model terms, in the order of their first appearance; chosen to stay apart from the
/// measured blue, the model black and the alert red.
const TERM_COLOURS: [RGBColor; 8] = [
    RGBColor(230, 140, 0),
    RGBColor(0, 150, 110),
    RGBColor(150, 70, 180),
    RGBColor(120, 90, 40),
    RGBColor(0, 160, 200),
    RGBColor(210, 80, 150),
    RGBColor(110, 140, 0),
    RGBColor(90, 90, 90),
];

/// Text style of the given size in the bundled font.
fn text(size: u32) -> TextStyle<'static> {
    (FONT, size).into_font().color(&BLACK)
}

/// The most decades one logarithmic axis may span. Allan plots of real IMUs span under 10; the
/// bound stops nonsense input (1e-300 next to 1e300) before plotters tries to tick it.
pub const MAX_DECADES: u32 = 40;

/// The error for an axis range `lo..hi` that plotters cannot draw, with the reason.
fn unplottable(
    figure: &'static str,
    field: &str,
    lo: f64,
    hi: f64,
    why: &'static str,
) -> ReportError {
    ReportError::UnplottableRange {
        figure,
        field: field.to_string(),
        low: lo,
        high: hi,
        why,
    }
}

/// Checks that `lo..hi` (both > 0) fits on one log axis: at most [`MAX_DECADES`], and inside
/// 1e-300..1e300 so that padding and rounding to decades cannot overflow to 0 or ∞ (plotters'
/// tick code never returns on an infinite range).
fn check_log_span(figure: &'static str, field: &str, lo: f64, hi: f64) -> Result<(), ReportError> {
    let why = if lo < 1e-300 || hi > 1e300 {
        "a log axis takes values within 1e-300..1e300"
    } else if (hi / lo).log10() > f64::from(MAX_DECADES) {
        "a log axis spans at most 40 decades"
    } else {
        return Ok(());
    };
    Err(unplottable(figure, field, lo, hi, why))
}

/// Checks that `lo..hi` can be a linear axis: within ±1e300 and a span of at least 10⁻⁹ of its
/// magnitude (plotters' tick code never returns when a tick step is below one ulp).
fn check_linear_span(
    figure: &'static str,
    field: &str,
    lo: f64,
    hi: f64,
) -> Result<(), ReportError> {
    let why = if lo.abs() > 1e300 || hi.abs() > 1e300 {
        "a linear axis takes values within ±1e300"
    } else if hi - lo < 1e-9 * lo.abs().max(hi.abs()) {
        "the span is too small against the size of the values"
    } else {
        return Ok(());
    };
    Err(unplottable(figure, field, lo, hi, why))
}

/// A log-axis range for data spanning `lo..hi` (both > 0) that shows labelled decades.
///
/// The data's range widened by `pad` (a factor, e.g. 1.25) when that already contains two decade
/// ticks; otherwise the enclosing whole decades, so that every log axis carries at least two
/// labelled decades and no axis wastes most of a decade on empty space.
fn log_range(lo: f64, hi: f64, pad: f64) -> std::ops::Range<f64> {
    let (plo, phi) = (lo / pad, hi * pad);
    if phi.log10().floor() - plo.log10().ceil() >= 1.0 {
        plo..phi
    } else {
        decade_range(lo, hi)
    }
}

/// The enclosing whole decades of `lo..hi` (both > 0).
fn decade_range(lo: f64, hi: f64) -> std::ops::Range<f64> {
    let lo_exp = lo.log10().floor();
    let mut hi_exp = hi.log10().ceil();
    if hi_exp <= lo_exp {
        hi_exp = lo_exp + 1.0;
    }
    10f64.powf(lo_exp)..10f64.powf(hi_exp)
}

/// `10ⁿ` for an exact decade, empty for the minor ticks in between.
fn decade_label(v: &f64) -> String {
    let e = v.log10();
    if (e - e.round()).abs() > 1e-6 {
        return String::new();
    }
    let e = e.round() as i32;
    if e == 0 {
        return "1".to_string();
    }
    const SUP: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut s = String::from("10");
    if e < 0 {
        s.push('⁻');
    }
    for d in e.unsigned_abs().to_string().bytes() {
        s.push(SUP[usize::from(d - b'0')]);
    }
    s
}

/// A plain number label with as few digits as the tick spacing needs.
fn plain_label(v: &f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".to_string()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.0e}")
    } else {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// `2.5×10⁻⁴`-style label for a value given as its base-10 logarithm (colour bars).
fn log10_label(e: &f64) -> String {
    let v = 10f64.powf(*e);
    let exp = v.log10().floor();
    let mantissa = v / 10f64.powf(exp);
    let decade = decade_label(&10f64.powf(exp));
    if (mantissa - 1.0).abs() < 0.05 {
        decade
    } else if exp == 0.0 {
        format!("{mantissa:.1}")
    } else {
        format!("{mantissa:.1}×{decade}")
    }
}

/// Edges of cells centred on sorted `centres`: midpoints between neighbours (geometric when
/// `log`), the outer edges half a step beyond the ends. One centre gets a cell of width 1 (or a
/// factor 10 in log).
fn cell_edges(centres: &[f64], log: bool) -> Vec<f64> {
    type Map = fn(f64) -> f64;
    let (fwd, inv): (Map, Map) = if log {
        (f64::ln, f64::exp)
    } else {
        (|v| v, |v| v)
    };
    let c: Vec<f64> = centres.iter().map(|&v| fwd(v)).collect();
    let n = c.len();
    if n == 0 {
        return Vec::new();
    }
    if n == 1 {
        let half = if log { 10f64.ln() / 2.0 } else { 0.5 };
        return vec![inv(c[0] - half), inv(c[0] + half)];
    }
    let mut edges = Vec::with_capacity(n + 1);
    edges.push(c[0] - (c[1] - c[0]) / 2.0);
    edges.extend(c.windows(2).map(|w| (w[0] + w[1]) / 2.0));
    edges.push(c[n - 1] + (c[n - 1] - c[n - 2]) / 2.0);
    edges.into_iter().map(inv).collect()
}

/// Min and max of finite values; `None` when there is none.
fn min_max(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// Draws `title` in a 44-pixel band at the top of `root` and returns the area below it.
fn draw_heading<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: String,
) -> Result<DrawingArea<DB, Shift>, DrawFailed> {
    use plotters::style::text_anchor::{HPos, Pos, VPos};
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(44);
    head.draw(&Text::new(
        title,
        (18, 12),
        text(24).pos(Pos::new(HPos::Left, VPos::Top)),
    ))?;
    Ok(body)
}

/// The figures' common mesh look: label and title fonts, light grid at the labelled ticks only.
fn mesh_look<'m, 'a, 'b, X, Y, DB>(
    mesh: &'m mut plotters::chart::MeshStyle<'a, 'b, X, Y, DB>,
) -> &'m mut plotters::chart::MeshStyle<'a, 'b, X, Y, DB>
where
    X: plotters::coord::ranged1d::Ranged,
    Y: plotters::coord::ranged1d::Ranged,
    DB: DrawingBackend,
{
    mesh.label_style(text(15))
        .axis_desc_style(text(17))
        .bold_line_style(GRID.stroke_width(1))
        .light_line_style(WHITE.mix(0.0))
}

/// Draws tick marks and labels at backend pixel positions (as `ChartContext::backend_coord`
/// returns them) into `area`: on the right of each point when `right`, else on its left.
///
/// For axes whose ticks plotters cannot place itself: the symmetric-log z axis and colour bars.
fn draw_ticks<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    ticks: &[((i32, i32), String)],
    right: bool,
) -> Drawn {
    use plotters::style::text_anchor::{HPos, Pos, VPos};
    let (bx, by) = area.get_base_pixel();
    let (dir, anchor) = if right {
        (1, HPos::Left)
    } else {
        (-1, HPos::Right)
    };
    let style = text(15).pos(Pos::new(anchor, VPos::Center));
    for ((x, y), label) in ticks {
        let (x, y) = (x - bx, y - by);
        area.draw(&PathElement::new(
            vec![(x, y), (x + 5 * dir, y)],
            BLACK.stroke_width(1),
        ))?;
        area.draw(&Text::new(label.clone(), (x + 8 * dir, y), style.clone()))?;
    }
    Ok(())
}

/// A legend entry drawn in a strip of its own.
enum LegendMark {
    /// A solid line of the given colour and width.
    Line(RGBColor, u32),
    /// A dashed line.
    Dashed(RGBColor),
    /// A filled box (band or shaded range).
    Fill(RGBAColor),
    /// A dot with a line through it (measured points).
    Points(RGBColor),
    /// A hollow dot (measured points bridged over lost samples).
    Hollow(RGBColor),
}

/// Draws legend entries top-down in `area` (a strip beside the plots).
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(LegendMark, String)],
    top: i32,
) -> Drawn {
    let row = 26;
    for (i, (mark, label)) in entries.iter().enumerate() {
        let y = top + row * i as i32;
        let (x0, x1) = (8, 44);
        match mark {
            LegendMark::Line(c, w) => area.draw(&PathElement::new(
                vec![(x0, y), (x1, y)],
                c.stroke_width(*w),
            ))?,
            LegendMark::Dashed(c) => area.draw(&plotters::element::DashedPathElement::new(
                vec![(x0, y), (x1, y)],
                7,
                4,
                c.stroke_width(2),
            ))?,
            LegendMark::Fill(c) => {
                area.draw(&Rectangle::new([(x0, y - 7), (x1, y + 7)], c.filled()))?
            }
            LegendMark::Points(c) => {
                area.draw(&PathElement::new(vec![(x0, y), (x1, y)], c.stroke_width(1)))?;
                area.draw(&Circle::new(((x0 + x1) / 2, y), 3, c.filled()))?;
            }
            LegendMark::Hollow(c) => {
                area.draw(&Circle::new(((x0 + x1) / 2, y), 3, c.stroke_width(2)))?;
            }
        }
        area.draw(&Text::new(
            label.clone(),
            (x1 + 8, y),
            text(15).pos(plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Left,
                plotters::style::text_anchor::VPos::Center,
            )),
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decade_labels_use_superscripts() {
        assert_eq!(decade_label(&1e-3), "10⁻³");
        assert_eq!(decade_label(&100.0), "10²");
        assert_eq!(decade_label(&1.0), "1");
        assert_eq!(decade_label(&1e12), "10¹²");
        assert_eq!(decade_label(&3e-3), "");
    }

    #[test]
    fn log_range_is_tight_when_two_decades_show() {
        let r = log_range(0.02, 800.0, 1.25);
        assert!((r.start - 0.016).abs() < 1e-12 && (r.end - 1000.0).abs() < 1e-9);
        // 2e-5..3e-3 holds 1e-4 and 1e-3: tight.
        let r = log_range(2e-5, 3e-3, 1.25);
        assert!((r.start - 1.6e-5).abs() < 1e-18);
        // 2e-5..5e-4 holds only 1e-4: whole decades.
        let r = log_range(2e-5, 5e-4, 1.25);
        assert!((r.start - 1e-5).abs() < 1e-20 && (r.end - 1e-3).abs() < 1e-15);
    }

    #[test]
    fn decade_range_encloses_whole_decades() {
        let r = decade_range(0.03, 250.0);
        assert!((r.start - 0.01).abs() < 1e-15 && (r.end - 1000.0).abs() < 1e-9);
        let r = decade_range(2.0, 3.0);
        assert!((r.start - 1.0).abs() < 1e-15 && (r.end - 10.0).abs() < 1e-12);
    }

    #[test]
    fn colour_bar_labels() {
        assert_eq!(log10_label(&-4.0), "10⁻⁴");
        assert_eq!(log10_label(&(2.5e-4f64).log10()), "2.5×10⁻⁴");
        assert_eq!(log10_label(&(3.0f64).log10()), "3.0");
    }

    #[test]
    fn cell_edges_are_midpoints() {
        assert_eq!(
            cell_edges(&[0.0, 1.0, 3.0], false),
            vec![-0.5, 0.5, 2.0, 4.0]
        );
        let e = cell_edges(&[1.0, 4.0], true);
        let want = [0.5, 2.0, 8.0];
        assert!(
            e.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-12),
            "{e:?}"
        );
    }

    #[test]
    fn suffix_keeps_dots_in_stem() {
        assert_eq!(
            with_suffix(Path::new("out/gyro_x.allan"), "png"),
            PathBuf::from("out/gyro_x.allan.png")
        );
    }
}

//! The F value and window length over time: two stacked panels, as the seed's Figs. 3–4.
use serde::{Deserialize, Serialize};

use super::*;

const FIGURE: &str = "window trace";

/// The adaptive window's trace over one record: F value, its reference F̃, and window length W.
///
/// Top panel: F(t) and F̃(t) (dashed). Bottom panel: W(t) as a staircase with the bounds λ1, λ2.
/// Event spans are shaded in both, so one sees F react and W shrink at a noise change.
/// NaN in `f_value` or `f_reference` means "no value yet" (warm-up) and breaks the line.
/// Write it with [`write_window_trace`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WindowTrace {
    /// Axis name (`gyro_x` … `accel_z`).
    pub axis: String,
    /// Figure title; the axis is added to it.
    pub title: String,
    /// Analysis times \[s from the first sample\], strictly increasing.
    pub times: Vec<f64>,
    /// F(t), the window variance over σ²_ref (dimensionless), one per time.
    pub f_value: Vec<f64>,
    /// F̃(t), the reference F; repeat the value for a fixed F̃, or give the learned `auto` value.
    pub f_reference: Vec<f64>,
    /// Window length W(t) \[samples\], one per time.
    pub window: Vec<usize>,
    /// The window bounds (λ1, λ2) \[samples\], drawn as guide lines when given.
    pub window_limits: Option<(usize, usize)>,
    /// Time spans \[start, end\] (s) where the noise changed; shaded.
    pub events: Vec<(f64, f64)>,
}

/// Writes the window trace to `<stem>.png` and `<stem>.svg` and returns both paths.
///
/// # Errors
/// [`ReportError`] when times are empty or not strictly increasing, a series has the wrong length,
/// F or F̃ is infinite or negative, no F value is finite, λ1 > λ2, or an event is reversed;
/// [`ReportError::Draw`] when a file cannot be written.
pub fn write_window_trace(trace: &WindowTrace, stem: &Path) -> Result<Vec<PathBuf>, ReportError> {
    write_figure(&Trace::new(trace)?, stem)
}

/// A validated trace with its axis ranges.
struct Trace<'a> {
    trace: &'a WindowTrace,
    f_max: f64,
    w_range: (f64, f64),
}

impl<'a> Trace<'a> {
    fn new(t: &'a WindowTrace) -> Result<Self, ReportError> {
        let n = t.times.len();
        check_non_empty(FIGURE, "times", n)?;
        check_increasing(FIGURE, "times", &t.times)?;
        check_len(FIGURE, "f_value", t.f_value.len(), "times", n)?;
        check_len(FIGURE, "f_reference", t.f_reference.len(), "times", n)?;
        check_len(FIGURE, "window", t.window.len(), "times", n)?;
        for (field, values) in [("f_value", &t.f_value), ("f_reference", &t.f_reference)] {
            check_values(
                FIGURE,
                field,
                values.iter().copied(),
                Need::NonNegative,
                true,
            )?;
        }
        check_intervals(FIGURE, "events", &t.events, false)?;
        if let Some((l1, l2)) = t.window_limits {
            check_intervals(FIGURE, "window_limits", &[(l1 as f64, l2 as f64)], false)?;
        }
        let Some((_, f_hi)) = min_max(t.f_value.iter().chain(&t.f_reference).copied()) else {
            return Err(ReportError::Empty {
                figure: FIGURE,
                field: "f_value (every value is NaN)".into(),
            });
        };
        let limits = t.window_limits.map(|(a, b)| [a as f64, b as f64]);
        let (w_lo, w_hi) = min_max(
            t.window
                .iter()
                .map(|&w| w as f64)
                .chain(limits.into_iter().flatten()),
        )
        .unwrap_or((0.0, 1.0));
        let pad = ((w_hi - w_lo) * 0.08).max(2.0);
        Ok(Trace {
            trace: t,
            f_max: (f_hi * 1.1).max(1e-12),
            w_range: ((w_lo - pad).max(0.0), w_hi + pad),
        })
    }
}

/// Runs of finite (t, v) points, so NaN breaks a line instead of ending it.
fn finite_runs(times: &[f64], values: &[f64]) -> Vec<Vec<(f64, f64)>> {
    let mut runs = Vec::new();
    let mut run = Vec::new();
    for (&t, &v) in times.iter().zip(values) {
        if v.is_finite() {
            run.push((t, v));
        } else if !run.is_empty() {
            runs.push(std::mem::take(&mut run));
        }
    }
    if !run.is_empty() {
        runs.push(run);
    }
    runs
}

impl Figure for Trace<'_> {
    fn size(&self) -> (u32, u32) {
        (1250, 780)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Drawn {
        let t = self.trace;
        let (w, h) = root.dim_in_pixel();
        let heading = if t.title.is_empty() {
            format!("Adaptive window — {}", t.axis)
        } else {
            format!("{} — adaptive window — {}", t.title, t.axis)
        };
        let body = draw_heading(root, heading)?;
        let (plots, legend) = body.split_horizontally(w - 230);
        let (top, bottom) = plots.split_vertically((h - 44) / 2);
        let x = t.times[0]..t.times[t.times.len() - 1].max(t.times[0] + 1e-9);

        let mut fc = ChartBuilder::on(&top)
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(x.clone(), 0.0..self.f_max)?;
        mesh_look(&mut fc.configure_mesh())
            .y_desc("F value (window var / σ²_ref)")
            .x_labels(10)
            .y_labels(8)
            .x_label_formatter(&plain_label)
            .y_label_formatter(&plain_label)
            .draw()?;
        fc.draw_series(
            t.events
                .iter()
                .map(|&(a, b)| Rectangle::new([(a, 0.0), (b, self.f_max)], SHADE.filled())),
        )?;
        for run in finite_runs(&t.times, &t.f_reference) {
            fc.draw_series(DashedLineSeries::new(run, 8, 5, ALERT.stroke_width(2)))?;
        }
        for run in finite_runs(&t.times, &t.f_value) {
            fc.draw_series(LineSeries::new(run, MEASURED.stroke_width(2)))?;
        }

        let (w_lo, w_hi) = self.w_range;
        let mut wc = ChartBuilder::on(&bottom)
            .margin(10)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(x.clone(), w_lo..w_hi)?;
        mesh_look(&mut wc.configure_mesh())
            .x_desc("analysis time t [s]")
            .y_desc("window length W [samples]")
            .x_labels(10)
            .y_labels(8)
            .x_label_formatter(&plain_label)
            .y_label_formatter(&plain_label)
            .draw()?;
        wc.draw_series(
            t.events
                .iter()
                .map(|&(a, b)| Rectangle::new([(a, w_lo), (b, w_hi)], SHADE.filled())),
        )?;
        if let Some((l1, l2)) = t.window_limits {
            for l in [l1, l2] {
                wc.draw_series(DashedLineSeries::new(
                    [(x.start, l as f64), (x.end, l as f64)],
                    8,
                    5,
                    RGBColor(110, 110, 110).stroke_width(2),
                ))?;
            }
        }
        // W holds from one analysis time to the next: a staircase.
        let stairs = t
            .times
            .iter()
            .zip(&t.window)
            .enumerate()
            .flat_map(|(i, (&ti, &wi))| {
                let next = t.times.get(i + 1).copied().unwrap_or(ti);
                [(ti, wi as f64), (next, wi as f64)]
            });
        wc.draw_series(LineSeries::new(stairs, BLACK.stroke_width(2)))?;

        let mut entries = vec![
            (LegendMark::Line(MEASURED, 2), "F value".to_string()),
            (LegendMark::Dashed(ALERT), "F reference".to_string()),
            (LegendMark::Line(BLACK, 2), "window length W".to_string()),
        ];
        if t.window_limits.is_some() {
            entries.push((
                LegendMark::Dashed(RGBColor(110, 110, 110)),
                "λ1, λ2 (bounds)".to_string(),
            ));
        }
        if !t.events.is_empty() {
            entries.push((LegendMark::Fill(SHADE), "events".to_string()));
        }
        draw_legend(&legend, &entries, 60)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_breaks_runs() {
        let runs = finite_runs(
            &[0.0, 1.0, 2.0, 3.0, 4.0],
            &[f64::NAN, 1.0, f64::NAN, 2.0, 3.0],
        );
        assert_eq!(runs, vec![vec![(1.0, 1.0)], vec![(3.0, 2.0), (4.0, 3.0)]]);
    }
}

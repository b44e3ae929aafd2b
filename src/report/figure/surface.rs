//! The DAVAR surface σ(t, τ) as a heatmap: analysis time across, τ up (log), colour = log σ.
use serde::{Deserialize, Serialize};

use super::*;

const FIGURE: &str = "davar surface";

/// At most this many time columns are drawn; longer records are binned (geometric mean of the
/// rows in each bin), which keeps the SVG small and loses nothing a screen could show.
pub const SURFACE_MAX_COLUMNS: usize = 600;

/// The DAVAR surface of one axis: one row σ(t, τ) per analysis time.
///
/// `dev\[i\]\[j\]` is the Allan deviation at analysis time `times\[i\]` and averaging time `taus\[j\]`;
/// NaN means "no value" (τ beyond the window's τmax = W/3, or a term left out at a gap) and is
/// drawn grey. Write it with [`write_davar_surface`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DavarSurface {
    /// Axis name (`gyro_x` … `accel_z`).
    pub axis: String,
    /// Unit of σ (e.g. `rad/s`), shown on the colour bar.
    pub unit: String,
    /// Figure title; the axis is added to it.
    pub title: String,
    /// Analysis times \[s from the first sample\], strictly increasing.
    pub times: Vec<f64>,
    /// Averaging times τ \[s\], strictly increasing.
    pub taus: Vec<f64>,
    /// σ(t, τ): one row per time, one column per τ; NaN = no value.
    pub dev: Vec<Vec<f64>>,
    /// Time spans \[start, end\] (s) where the DAVAR saw the noise change; marked by dashed lines.
    pub events: Vec<(f64, f64)>,
}

/// Writes the DAVAR heatmap to `<stem>.png` and `<stem>.svg` and returns both paths.
///
/// Records longer than [`SURFACE_MAX_COLUMNS`] analysis times are binned in time for drawing.
///
/// # Errors
/// [`ReportError`] when times or τ are empty or not strictly increasing, τ ≤ 0, a row has the wrong
/// length, a σ is infinite or ≤ 0, every σ is NaN, or an event is reversed;
/// [`ReportError::Draw`] when a file cannot be written.
pub fn write_davar_surface(
    surface: &DavarSurface,
    stem: &Path,
) -> Result<Vec<PathBuf>, ReportError> {
    write_figure(&Heatmap::new(surface)?, stem)
}

/// A validated, binned surface ready to draw.
struct Heatmap<'a> {
    surface: &'a DavarSurface,
    /// Time edges of the drawn columns (len = columns + 1).
    t_edges: Vec<f64>,
    /// τ edges of the rows (len = taus + 1).
    tau_edges: Vec<f64>,
    /// log10 σ per drawn column and τ; NaN = no value.
    log_dev: Vec<Vec<f64>>,
    /// Colour scale range in log10 σ.
    log_range: (f64, f64),
}

impl<'a> Heatmap<'a> {
    fn new(s: &'a DavarSurface) -> Result<Self, ReportError> {
        check_non_empty(FIGURE, "times", s.times.len())?;
        check_non_empty(FIGURE, "taus", s.taus.len())?;
        check_increasing(FIGURE, "times", &s.times)?;
        check_increasing(FIGURE, "taus", &s.taus)?;
        check_positive(FIGURE, "taus", s.taus.iter().copied())?;
        check_len(FIGURE, "dev", s.dev.len(), "times", s.times.len())?;
        for (i, row) in s.dev.iter().enumerate() {
            let field = format!("dev[{i}]");
            check_len(FIGURE, &field, row.len(), "taus", s.taus.len())?;
            check_values(FIGURE, &field, row.iter().copied(), Need::Positive, true)?;
        }
        check_intervals(FIGURE, "events", &s.events, false)?;
        let Some((lo, hi)) = min_max(s.dev.iter().flatten().copied()) else {
            return Err(ReportError::Empty {
                figure: FIGURE,
                field: "dev (every value is NaN)".into(),
            });
        };
        let log_range = if hi > lo {
            (lo.log10(), hi.log10())
        } else {
            (lo.log10() - 0.5, lo.log10() + 0.5)
        };

        let all_edges = cell_edges(&s.times, false);
        let n = s.times.len();
        let columns = n.min(SURFACE_MAX_COLUMNS);
        let mut t_edges = Vec::with_capacity(columns + 1);
        let mut log_dev = Vec::with_capacity(columns);
        for k in 0..columns {
            let (a, b) = (k * n / columns, (k + 1) * n / columns);
            t_edges.push(all_edges[a]);
            log_dev.push(
                (0..s.taus.len())
                    .map(|j| {
                        let logs: Vec<f64> = s.dev[a..b]
                            .iter()
                            .map(|row| row[j])
                            .filter(|v| !v.is_nan())
                            .map(f64::log10)
                            .collect();
                        if logs.is_empty() {
                            f64::NAN
                        } else {
                            logs.iter().sum::<f64>() / logs.len() as f64
                        }
                    })
                    .collect(),
            );
        }
        t_edges.push(all_edges[n]);
        Ok(Heatmap {
            surface: s,
            t_edges,
            tau_edges: cell_edges(&s.taus, true),
            log_dev,
            log_range,
        })
    }
}

/// Viridis colour of a log10 σ within the scale.
fn colour(log_dev: f64, (lo, hi): (f64, f64)) -> RGBColor {
    ViridisRGB::get_color_normalized(log_dev, lo, hi)
}

impl Figure for Heatmap<'_> {
    fn size(&self) -> (u32, u32) {
        (1200, 700)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Drawn {
        let s = self.surface;
        let (w, _) = root.dim_in_pixel();
        let heading = if s.title.is_empty() {
            format!("DAVAR surface σ(t, τ) — {}", s.axis)
        } else {
            format!("{} — DAVAR surface σ(t, τ) — {}", s.title, s.axis)
        };
        let body = draw_heading(root, heading)?;
        let (main, bar) = body.split_horizontally(w - 190);

        let t_range = self.t_edges[0]..self.t_edges[self.t_edges.len() - 1];
        let (tau_lo, tau_hi) = (self.tau_edges[0], self.tau_edges[self.tau_edges.len() - 1]);
        // The cells fill the plot; widen to whole decades only if no decade would be labelled.
        let tau_range = if tau_hi.log10().floor() >= tau_lo.log10().ceil() {
            tau_lo..tau_hi
        } else {
            decade_range(tau_lo, tau_hi)
        };
        let mut chart = ChartBuilder::on(&main)
            .margin(10)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(t_range.clone(), tau_range.clone().log_scale())?;
        mesh_look(&mut chart.configure_mesh())
            .disable_mesh()
            .x_desc("analysis time t [s]")
            .y_desc("τ [s]")
            .x_labels(10)
            .y_labels(40)
            .x_label_formatter(&plain_label)
            .y_label_formatter(&decade_label)
            .draw()?;
        // Grey for "no value", then one rectangle per cell that has one.
        chart.draw_series(std::iter::once(Rectangle::new(
            [
                (t_range.start, self.tau_edges[0]),
                (t_range.end, *self.tau_edges.last().unwrap_or(&1.0)),
            ],
            RGBColor(215, 215, 215).filled(),
        )))?;
        chart.draw_series(self.log_dev.iter().enumerate().flat_map(|(k, col)| {
            col.iter()
                .enumerate()
                .filter(|(_, v)| !v.is_nan())
                .map(move |(j, &v)| {
                    Rectangle::new(
                        [
                            (self.t_edges[k], self.tau_edges[j]),
                            (self.t_edges[k + 1], self.tau_edges[j + 1]),
                        ],
                        colour(v, self.log_range).filled(),
                    )
                })
        }))?;
        for &(start, end) in &s.events {
            for t in [start, end] {
                chart.draw_series(DashedLineSeries::new(
                    [(t, tau_range.start), (t, tau_range.end)],
                    8,
                    5,
                    WHITE.stroke_width(2),
                ))?;
            }
        }

        // Colour bar: log10 σ on a linear axis so it is labelled whatever its span; labels are
        // drawn on its right, where they cannot collide with the heatmap.
        let (lo, hi) = self.log_range;
        let mut cb = ChartBuilder::on(&bar)
            .margin_top(30)
            .margin_bottom(55)
            .margin_left(10)
            .margin_right(120)
            .build_cartesian_2d(0.0..1.0, lo..hi)?;
        let steps = 120;
        cb.draw_series((0..steps).map(|i| {
            let a = lo + (hi - lo) * i as f64 / steps as f64;
            let b = lo + (hi - lo) * (i + 1) as f64 / steps as f64;
            Rectangle::new(
                [(0.0, a), (1.0, b)],
                colour((a + b) / 2.0, self.log_range).filled(),
            )
        }))?;
        let scale: plotters::coord::types::RangedCoordf64 = (lo..hi).into();
        let ticks: Vec<((i32, i32), String)> = scale
            .key_points(7)
            .into_iter()
            .map(|tick| (cb.backend_coord(&(1.0, tick)), log10_label(&tick)))
            .collect();
        draw_ticks(&bar, &ticks, true)?;
        bar.draw(&Text::new(format!("σ [{}]", s.unit), (10, 4), text(16)))?;
        let (_, bar_h) = bar.dim_in_pixel();
        bar.draw(&Text::new(
            "grey: no value",
            (8, bar_h as i32 - 30),
            text(14),
        ))?;
        if !s.events.is_empty() {
            bar.draw(&Text::new(
                "dashed: events",
                (8, bar_h as i32 - 14),
                text(14),
            ))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn surface(n: usize) -> DavarSurface {
        DavarSurface {
            axis: "gyro_x".into(),
            unit: "rad/s".into(),
            title: String::new(),
            times: (0..n).map(|i| i as f64).collect(),
            taus: vec![0.1, 1.0],
            dev: (0..n).map(|i| vec![1.0 + i as f64, f64::NAN]).collect(),
            events: vec![],
        }
    }

    #[test]
    fn long_records_are_binned_by_geometric_mean() {
        let s = surface(2 * SURFACE_MAX_COLUMNS);
        let h = Heatmap::new(&s).unwrap();
        assert_eq!(h.log_dev.len(), SURFACE_MAX_COLUMNS);
        assert_eq!(h.t_edges.len(), SURFACE_MAX_COLUMNS + 1);
        // Column 0 holds rows 0 and 1: σ = 1 and 2 → log10 √2.
        assert!((h.log_dev[0][0] - 2f64.sqrt().log10()).abs() < 1e-12);
        assert!(h.log_dev[0][1].is_nan());
    }

    #[test]
    fn error_index_points_into_the_row() {
        let mut s = surface(3);
        s.dev[1] = vec![f64::NAN, -1.0];
        match Heatmap::new(&s) {
            Err(ReportError::NotPositive { field, index, .. }) => {
                assert_eq!((field.as_str(), index), ("dev[1]", 1));
            }
            other => panic!("expected NotPositive, got {:?}", other.err()),
        }
    }
}

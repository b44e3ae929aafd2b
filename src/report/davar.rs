//! The F-DAVAR figures of a recording (`fdavar davar --out DIR`), gathered while its rows stream by.
//!
//! A 24 h recording at 200 Hz makes 17 million rows per axis; holding them to draw a figure 1200
//! pixels wide would make memory grow with the recording, which `fdavar davar` is built not to do
//! (it streams). [`DavarFigures`] therefore keeps at most [`MAX_BINS`] time bins per axis: while
//! there are fewer rows, one row per bin; when the bins are full, neighbours are merged in pairs
//! and each bin then takes twice as many rows. Merging is exact because every kept quantity is
//! a sum, a count, a maximum or a minimum. The rejected alternatives: thinning by time
//! (`davar::Thinning`) needs the recording's length before the first row, and keeping every k-th
//! row would drop a short noise burst between two kept rows.
use std::collections::BTreeMap;

use crate::davar::ChangeEvent;
use crate::pipeline::AxisRow;
use crate::report::figure::{DavarSurface, WindowTrace, SURFACE_MAX_COLUMNS};
use crate::signal::Axis;

/// Most time bins kept per axis: twice what the surface draws, so that the figure's own binning
/// (geometric mean over equal shares of the bins) still has at least one bin per column.
pub const MAX_BINS: usize = 2 * SURFACE_MAX_COLUMNS;

/// The rows of one time bin, reduced.
#[derive(Debug, Clone)]
struct Bin {
    /// Analysis time of the bin's first row, s.
    time_s: f64,
    /// Rows in the bin.
    rows: u64,
    /// Per averaging factor m: (τ \[s\], Σ ln σ, number of σ summed).
    log_dev: BTreeMap<usize, (f64, f64, u32)>,
    /// The largest F of the bin's rows; NaN while none is known.
    f_max: f64,
    /// F̃ of the bin's last row; NaN while it is being learned.
    f_reference: f64,
    /// The shortest window of the bin's rows, samples.
    window_min: usize,
}

impl Bin {
    fn new(r: &AxisRow) -> Bin {
        Bin {
            time_s: r.time_s,
            rows: 0,
            log_dev: BTreeMap::new(),
            f_max: f64::NAN,
            f_reference: f64::NAN,
            window_min: r.row.window,
        }
    }

    fn add(&mut self, r: &AxisRow) {
        self.rows += 1;
        for p in r.row.points() {
            let dev = p.adev();
            // A σ of 0 has no place on the log colour scale: no value, as a gap.
            if dev > 0.0 && dev.is_finite() {
                let e = self.log_dev.entry(p.m).or_insert((p.tau, 0.0, 0));
                e.1 += dev.ln();
                e.2 += 1;
            }
        }
        if let Some(f) = r.row.f.filter(|f| f.is_finite()) {
            self.f_max = if self.f_max.is_nan() { f } else { self.f_max.max(f) };
        }
        self.f_reference = r.row.f_target.unwrap_or(f64::NAN);
        self.window_min = self.window_min.min(r.row.window);
    }

    /// This bin followed by `next`, as one.
    fn merge(mut self, next: Bin) -> Bin {
        self.rows += next.rows;
        for (m, (tau, sum, n)) in next.log_dev {
            let e = self.log_dev.entry(m).or_insert((tau, 0.0, 0));
            e.1 += sum;
            e.2 += n;
        }
        self.f_max = match (self.f_max.is_nan(), next.f_max.is_nan()) {
            (true, _) => next.f_max,
            (_, true) => self.f_max,
            _ => self.f_max.max(next.f_max),
        };
        if !next.f_reference.is_nan() {
            self.f_reference = next.f_reference;
        }
        self.window_min = self.window_min.min(next.window_min);
        self
    }
}

/// The DAVAR surface and window trace of one axis, built from its rows in bounded memory.
///
/// Push every row of the axis ([`DavarFigures::push`]) and its change events, then take the
/// figures with [`DavarFigures::figures`]. A bin draws as: σ(τ) the geometric mean of its rows'
/// deviations at that τ (what the surface figure does when it bins), F the largest of its rows'
/// and W the shortest (so a brief reaction to a noise change stays visible however long the
/// recording), F̃ its last row's.
///
/// ```
/// use fdavar::report::davar::{DavarFigures, MAX_BINS};
/// use fdavar::signal::Axis;
/// let f = DavarFigures::new(Axis::GyroX, Some((100, 1000)));
/// assert_eq!(f.rows_per_bin(), 1);
/// assert!(f.figures("run").is_none()); // no rows yet
/// ```
#[derive(Debug, Clone)]
pub struct DavarFigures {
    axis: Axis,
    window_limits: Option<(usize, usize)>,
    /// Rows per full bin: a power of two.
    stride: u64,
    bins: Vec<Bin>,
    events: Vec<(f64, f64)>,
}

impl DavarFigures {
    /// An empty collector for `axis`; `window_limits` (λ1, λ2) are drawn as guide lines.
    pub fn new(axis: Axis, window_limits: Option<(usize, usize)>) -> DavarFigures {
        DavarFigures {
            axis,
            window_limits,
            stride: 1,
            bins: Vec::new(),
            events: Vec::new(),
        }
    }

    /// Rows each bin takes now (1 until [`MAX_BINS`] rows have been pushed, then doubling).
    pub fn rows_per_bin(&self) -> u64 {
        self.stride
    }

    /// Adds one row of this collector's axis (rows of other axes are ignored).
    pub fn push(&mut self, r: &AxisRow) {
        if r.axis != self.axis {
            return;
        }
        let starts_bin = self.bins.last().is_none_or(|b| b.rows >= self.stride && r.time_s > b.time_s);
        if starts_bin {
            if self.bins.len() == MAX_BINS {
                let bins = std::mem::take(&mut self.bins);
                let mut it = bins.into_iter();
                while let Some(a) = it.next() {
                    self.bins.push(match it.next() {
                        Some(b) => a.merge(b),
                        None => a,
                    });
                }
                self.stride *= 2;
            }
            if self.bins.last().is_none_or(|b| b.rows >= self.stride) {
                self.bins.push(Bin::new(r));
            }
        }
        if let Some(b) = self.bins.last_mut() {
            b.add(r);
        }
    }

    /// Adds a change event (of any axis; only this axis's are kept).
    pub fn push_event(&mut self, axis: Axis, e: &ChangeEvent) {
        if axis == self.axis {
            self.events.push((e.start_s, e.end_s));
        }
    }

    /// The surface and the window trace, titled `title`; `None` before the first row.
    pub fn figures(&self, title: &str) -> Option<(DavarSurface, WindowTrace)> {
        if self.bins.is_empty() {
            return None;
        }
        let mut grid: BTreeMap<usize, f64> = BTreeMap::new();
        for b in &self.bins {
            for (&m, &(tau, _, _)) in &b.log_dev {
                grid.insert(m, tau);
            }
        }
        let times: Vec<f64> = self.bins.iter().map(|b| b.time_s).collect();
        let dev = self
            .bins
            .iter()
            .map(|b| {
                grid.keys()
                    .map(|m| match b.log_dev.get(m) {
                        Some(&(_, sum, n)) if n > 0 => (sum / f64::from(n)).exp(),
                        _ => f64::NAN,
                    })
                    .collect()
            })
            .collect();
        let surface = DavarSurface {
            axis: self.axis.name().to_string(),
            unit: self.axis.rate_unit().to_string(),
            title: title.to_string(),
            times: times.clone(),
            taus: grid.values().copied().collect(),
            dev,
            events: self.events.clone(),
        };
        let trace = WindowTrace {
            axis: self.axis.name().to_string(),
            title: title.to_string(),
            times,
            f_value: self.bins.iter().map(|b| b.f_max).collect(),
            f_reference: self.bins.iter().map(|b| b.f_reference).collect(),
            window: self.bins.iter().map(|b| b.window_min).collect(),
            window_limits: self.window_limits,
            events: self.events.clone(),
        };
        Some((surface, trace))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allan::AllanPoint;
    use crate::davar::DavarRow;

    /// Row `i` of a synthetic axis: σ(τ=0.01) = 1 + i mod 7, σ(τ=0.02) only on even rows, F = i,
    /// W = 100 − i mod 50.
    fn row(i: u64) -> AxisRow {
        let point = |m: usize, dev: f64| AllanPoint {
            m,
            tau: 0.01 * m as f64,
            avar: dev * dev,
            terms: 10,
            edf: 5.0,
            ci_low: 0.0,
            ci_high: 1.0,
        };
        let mut points = vec![point(1, 1.0 + (i % 7) as f64)];
        if i.is_multiple_of(2) {
            points.push(point(2, 2.0));
        }
        AxisRow {
            axis: Axis::GyroY,
            time_s: 0.01 * i as f64,
            stamp_ns: 10_000_000 * i as i64,
            row: DavarRow {
                index: i,
                time_s: 0.01 * i as f64,
                window: 100 - (i % 50) as usize,
                valid_samples: 100,
                variance: 1.0,
                f: Some(i as f64),
                f_target: Some(1.0),
                sigma2_ref: Some(1.0),
                excluded_terms: 0,
                ..DavarRow::of_points(&points)
            },
        }
    }

    #[test]
    fn memory_is_bounded_and_bins_are_exact() {
        let mut f = DavarFigures::new(Axis::GyroY, None);
        let n = 10 * MAX_BINS as u64 + 3;
        for i in 0..n {
            f.push(&row(i));
            assert!(f.bins.len() <= MAX_BINS, "{} bins after {i} rows", f.bins.len());
        }
        // 10·MAX_BINS rows: the stride doubled to 16 (8 would need 10/8·MAX_BINS bins).
        assert_eq!(f.rows_per_bin(), 16);
        let (surface, trace) = f.figures("t").unwrap();
        assert_eq!(surface.taus, vec![0.01, 0.02]);
        let k = n.div_ceil(16) as usize;
        assert_eq!(surface.times.len(), k);
        // Bin 3 holds rows 48..64: geometric mean of 1 + i mod 7, largest F, shortest W.
        let rows: Vec<u64> = (48..64).collect();
        let log_mean = rows.iter().map(|&i| (1.0 + (i % 7) as f64).ln()).sum::<f64>() / 16.0;
        assert!((surface.dev[3][0] - log_mean.exp()).abs() <= 1e-12 * log_mean.exp());
        assert!((surface.dev[3][1] - 2.0).abs() <= 1e-12);
        assert_eq!(surface.times[3], 0.01 * 48.0);
        assert_eq!(trace.f_value[3], 63.0);
        assert_eq!(trace.window[3], rows.iter().map(|&i| 100 - (i % 50) as usize).min().unwrap());
        // Other axes' rows are ignored.
        let mut other = row(0);
        other.axis = Axis::GyroX;
        f.push(&other);
        assert_eq!(f.figures("t").unwrap().0.times.len(), k);
    }
}

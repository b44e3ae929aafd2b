//! Dynamic Allan variance: the streaming F-DAVAR engine, F value and window policies.
//!
//! For each analysis index t a window of W(t) rate samples centred on t cuts the signal (seed
//! Eq. 4–6); the overlapping Allan variance of the cut (Eq. 12) at every τ of the grid with
//! τ ≤ W/3 is one row of the DAVAR surface σ²(t, τ). The variance ratio of the window (Eq. 2),
//!
//! ```text
//! F(t) = [(1/n) Σ (y[i] − ȳ)²] / σ²_ref
//! ```
//!
//! (sum over the n valid samples of the window), drives the window length through a
//! [`WindowPolicy`]: fixed ([`FixedWindow`]), the seed's Eq. 3 ([`SignPolicy`]) or a bounded
//! proportional step ([`ProportionalPolicy`]).
//!
//! Flow: [`DavarEngine`] (one per axis) turns rate samples into [`DavarRow`]s; [`ChangeDetector`]
//! turns rows into [`ChangeEvent`]s (spans where the noise changed). [`crate::pipeline`] runs six of
//! each behind the stamp checks; [`crate::params`] builds their configuration from a ROS 2
//! parameter file.
//!
//! The open points of the seed (docs/design.md §3) are decided in [`mod@reference`] (σ²_ref and F̃), in
//! [`adaptive`] (Eq. 3 kept exactly; proportional step added), in [`engine`] (window placement,
//! rebasing) and in [`events`] (what a change point is).
//!
//! # References
//! - Yang H. et al., "A DAVAR improved algorithm based on adaptive window of σ² ratio", Electronics
//!   Optics & Control 23(10), 2016 (Eq. 2, 3, 4–6, 12; Table 1).
//! - Galleani L., Tavella P., "The dynamic Allan variance", IEEE TUFFC 56(3), 2009.
//! - Riley W. J., NIST SP 1065, 2008 (overlapping AVAR, EDF).

pub mod adaptive;
pub mod engine;
pub mod events;
pub mod fixed;
pub mod reference;
pub mod stats;

pub use adaptive::{ProportionalPolicy, SignPolicy};
pub use engine::{DavarEngine, EngineConfig};
pub use events::{ChangeDetector, ChangeEvent, DetectorConfig};
pub use fixed::FixedWindow;
pub use reference::{record_variance, FTarget, RobustLevel, SigmaRef};
pub use stats::{edf_overlapping, IntervalCache, SharedIntervals};

use crate::allan::AllanPoint;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Errors of the DAVAR engine.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DavarError {
    /// The engine configuration is inconsistent.
    #[error("invalid DAVAR configuration: {reason}")]
    Config {
        /// What is wrong, with the offending values.
        reason: String,
    },
}

/// The range [λ1, λ2] a window length stays in, samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct WindowBounds {
    /// λ1, the shortest window.
    pub min: usize,
    /// λ2, the longest window (sets the engine's memory: O(K·λ2)).
    pub max: usize,
}

impl WindowBounds {
    /// `w` clamped into [min, max] (negative values give `min`).
    pub fn clamp(&self, w: i64) -> usize {
        w.clamp(self.min as i64, self.max as i64) as usize
    }
}

/// How the window length evolves from one analysis index to the next.
///
/// Object-safe so that the engine holds a `Box<dyn WindowPolicy>`; tests drive the engine with
/// scripted random sequences through the same trait.
pub trait WindowPolicy: Send {
    /// The policy's name (`fixed`, `sign`, `proportional`).
    fn name(&self) -> &'static str;
    /// The bounds every returned length lies in (the engine clamps to them as well).
    fn bounds(&self) -> WindowBounds;
    /// W at the first analysis index.
    fn initial(&self) -> usize;
    /// W(t+1) from W(t), F(t) and F̃ (either may be unknown: `None`).
    fn next(&mut self, w: usize, f: Option<f64>, f_target: Option<f64>) -> usize;
}

/// One row of the DAVAR surface: the analysis of one window.
///
/// Its points are held as the Allan variance at each τ beside the [`RowLayout`] that the rows of
/// one window share (each point's factor, τ, number of terms, EDF and interval factors), so that
/// a row of K points writes K numbers rather than K seven-field [`AllanPoint`]s: writing those was
/// 8 % of the CPU of `fdavar analyze` (docs/performance.md). [`DavarRow::points`] gives the points;
/// serialised, a row has them in full (`points`), as before.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DavarRow {
    /// Analysis index t: the sample at the window's centre, counted from the first sample pushed.
    pub index: u64,
    /// Analysis time t·τ0, seconds from the first sample.
    pub time_s: f64,
    /// Window length W(t), samples.
    pub window: usize,
    /// Valid samples inside the window.
    pub valid_samples: usize,
    /// Variance (1/n) of the valid samples of the window (the numerator of F).
    pub variance: f64,
    /// F(t) (seed Eq. 2); `None` while σ²_ref is unknown.
    pub f: Option<f64>,
    /// F̃ used to choose W(t+1); `None` while it is being learned.
    pub f_target: Option<f64>,
    /// σ²_ref used for F(t).
    pub sigma2_ref: Option<f64>,
    /// Squared differences of this row left out because they straddled an invalid sample.
    pub excluded_terms: usize,
    /// σ²(τ) of each point of `layout`.
    pub(crate) avars: Vec<f64>,
    /// What the points share with the other rows of this window; `None` only in a row whose
    /// parts were handed back to its engine ([`crate::pipeline::Pipeline::recycle_all`]), which
    /// then has no points.
    pub(crate) layout: Option<Arc<RowLayout>>,
}

/// The points of a row but their Allan variance: what the rows of one window share.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RowLayout {
    /// The window W of the rows that share it; 0 for the layout of one row with invalid samples
    /// (or one made by hand), which no other row shares.
    pub(crate) window: usize,
    /// One per point, ascending in τ.
    pub(crate) points: Vec<PointLayout>,
}

/// One point of a [`RowLayout`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PointLayout {
    pub(crate) m: usize,
    pub(crate) tau: f64,
    pub(crate) terms: usize,
    pub(crate) edf: f64,
    /// The confidence interval's bounds over σ²(τ).
    pub(crate) low: f64,
    pub(crate) high: f64,
}

impl PointLayout {
    fn point(&self, avar: f64) -> AllanPoint {
        AllanPoint {
            m: self.m,
            tau: self.tau,
            avar,
            terms: self.terms,
            edf: self.edf,
            ci_low: avar * self.low,
            ci_high: avar * self.high,
        }
    }
}

impl DavarRow {
    /// Overlapping Allan variance of the cut at each τ of the grid with 3m ≤ W and at least one
    /// valid term, ascending in τ.
    pub fn points(&self) -> impl ExactSizeIterator<Item = AllanPoint> + '_ {
        let layout = self.layout.as_deref().map_or(&[][..], |l| &l.points[..]);
        layout.iter().zip(&self.avars).map(|(l, &avar)| l.point(avar))
    }

    /// The point at the shortest τ (the one the change detector reads), if the row has any.
    pub fn first_point(&self) -> Option<AllanPoint> {
        self.points().next()
    }

    /// A row of `points`, its other fields zero (set them as needed): rows made by hand, in
    /// tests. Each interval is kept as its ratio to σ²(τ), so a point with σ²(τ) = 0 gets an
    /// interval of 0.
    pub fn of_points(points: &[AllanPoint]) -> DavarRow {
        let ratio = |ci: f64, avar: f64| if avar != 0.0 { ci / avar } else { 0.0 };
        let layout = RowLayout {
            window: 0,
            points: points
                .iter()
                .map(|p| PointLayout {
                    m: p.m,
                    tau: p.tau,
                    terms: p.terms,
                    edf: p.edf,
                    low: ratio(p.ci_low, p.avar),
                    high: ratio(p.ci_high, p.avar),
                })
                .collect(),
        };
        DavarRow {
            avars: points.iter().map(|p| p.avar).collect(),
            layout: Some(Arc::new(layout)),
            ..DavarRow::default()
        }
    }
}

/// A row read back from its serialised form ([`DavarRow::of_points`] keeps each interval as its
/// ratio to σ²(τ)).
impl<'de> Deserialize<'de> for DavarRow {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        struct Saved {
            index: u64,
            time_s: f64,
            window: usize,
            valid_samples: usize,
            variance: f64,
            f: Option<f64>,
            f_target: Option<f64>,
            sigma2_ref: Option<f64>,
            excluded_terms: usize,
            points: Vec<AllanPoint>,
        }
        let r = Saved::deserialize(deserializer)?;
        Ok(DavarRow {
            index: r.index,
            time_s: r.time_s,
            window: r.window,
            valid_samples: r.valid_samples,
            variance: r.variance,
            f: r.f,
            f_target: r.f_target,
            sigma2_ref: r.sigma2_ref,
            excluded_terms: r.excluded_terms,
            ..DavarRow::of_points(&r.points)
        })
    }
}

/// A row serialises as it always has: its fields, then `points` in full.
impl Serialize for DavarRow {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        struct Points<'a>(&'a DavarRow);
        impl Serialize for Points<'_> {
            fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                serializer.collect_seq(self.0.points())
            }
        }
        let mut row = serializer.serialize_struct("DavarRow", 10)?;
        row.serialize_field("index", &self.index)?;
        row.serialize_field("time_s", &self.time_s)?;
        row.serialize_field("window", &self.window)?;
        row.serialize_field("valid_samples", &self.valid_samples)?;
        row.serialize_field("variance", &self.variance)?;
        row.serialize_field("f", &self.f)?;
        row.serialize_field("f_target", &self.f_target)?;
        row.serialize_field("sigma2_ref", &self.sigma2_ref)?;
        row.serialize_field("excluded_terms", &self.excluded_terms)?;
        row.serialize_field("points", &Points(self))?;
        row.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows of a record with a gap: full windows (shared layouts) and windows with invalid samples.
    fn rows() -> Vec<DavarRow> {
        rows_recycling(false)
    }

    /// [`rows`], each row handed back to the engine after a copy is kept when `recycle`.
    fn rows_recycling(recycle: bool) -> Vec<DavarRow> {
        let cfg = EngineConfig {
            factors: vec![1, 2, 3, 5, 8],
            tau0: 0.01,
            sigma_ref: SigmaRef::Running,
            f_target: FTarget::Value(1.0),
        };
        let mut engine = DavarEngine::new(cfg, Box::new(FixedWindow::new(31))).unwrap();
        let (mut rows, mut out) = (Vec::new(), Vec::new());
        for k in 0..200u64 {
            let v = (k * 7919 % 101) as f64 * 1e-3;
            engine.push((!(90..94).contains(&k)).then_some(v), &mut out);
            for row in out.drain(..) {
                rows.push(row.clone());
                if recycle {
                    engine.recycle(row);
                }
            }
        }
        rows
    }

    #[test]
    fn recycled_rows_lend_their_memory_and_layout_without_changing_a_row() {
        // A gap in the record: full windows before and after it, whose rows take over the layout
        // handed back, and rows with invalid samples between, which make their own.
        assert_eq!(rows_recycling(true), rows_recycling(false));
    }

    #[test]
    fn a_row_serialises_its_fields_then_every_point_in_full() {
        let rows = rows();
        let gapped = rows.iter().find(|r| r.valid_samples < r.window).expect("a window over the gap");
        assert!(gapped.excluded_terms > 0);
        for row in [&rows[0], gapped] {
            let text = serde_json::to_string(row).unwrap();
            let keys = ["index", "time_s", "window", "valid_samples", "variance", "f", "f_target", "sigma2_ref", "excluded_terms", "points"];
            let at: Vec<usize> = keys.iter().map(|k| text.find(&format!("\"{k}\":")).expect(k)).collect();
            assert!(at.windows(2).all(|p| p[0] < p[1]), "{text}");
            let points = serde_json::to_string(&row.points().collect::<Vec<_>>()).unwrap();
            assert!(text.ends_with(&format!("\"points\":{points}}}")), "{text}");
            assert!(text.contains("\"window\":31,"), "{text}");
        }
        // A full row holds every factor with 3m ≤ W; the gapped one only factors with a valid term.
        assert_eq!(rows[0].points().map(|p| p.m).collect::<Vec<_>>(), [1, 2, 3, 5, 8]);
        assert!(gapped.points().all(|p| p.terms > 0 && p.terms <= 31 - 2 * p.m + 1));
    }

    #[test]
    fn rows_of_one_full_window_share_their_layout_and_read_back_from_json() {
        let rows = rows();
        let full: Vec<&DavarRow> = rows.iter().filter(|r| r.valid_samples == r.window).collect();
        let shared = |a: &DavarRow, b: &DavarRow| matches!((&a.layout, &b.layout), (Some(x), Some(y)) if Arc::ptr_eq(x, y));
        assert!(full.windows(2).all(|p| shared(p[0], p[1])));
        for row in [full[0], rows.iter().find(|r| r.valid_samples < r.window).unwrap()] {
            // serde_json reads a float back to within an ulp or two.
            let near = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b.abs();
            let back: DavarRow = serde_json::from_str(&serde_json::to_string(row).unwrap()).unwrap();
            assert_eq!((back.index, back.window, back.valid_samples), (row.index, row.window, row.valid_samples));
            assert!(near(back.f.unwrap(), row.f.unwrap()) && near(back.variance, row.variance));
            assert_eq!(back.points().len(), row.points().len());
            for (p, q) in back.points().zip(row.points()) {
                assert_eq!((p.m, p.terms), (q.m, q.terms));
                for (a, b) in [(p.tau, q.tau), (p.avar, q.avar), (p.edf, q.edf), (p.ci_low, q.ci_low), (p.ci_high, q.ci_high)] {
                    assert!(near(a, b), "{p:?} vs {q:?}");
                }
            }
        }
    }
}

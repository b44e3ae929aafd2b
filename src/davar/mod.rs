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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    /// Overlapping Allan variance of the cut at each τ of the grid with 3m ≤ W and at least one
    /// valid term, ascending in τ.
    pub points: Vec<AllanPoint>,
}

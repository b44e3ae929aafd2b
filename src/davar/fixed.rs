//! The fixed window: classic DAVAR (Galleani 2009), and the seed's "window 171 / 501" baselines.

use super::{WindowBounds, WindowPolicy};

/// A window whose length never changes.
///
/// The reference against which the adaptive policies are judged (seed Table 1, rows "窗长 171" and
/// "窗长 501").
///
/// ```
/// use fdavar::davar::{FixedWindow, WindowPolicy};
/// let mut p = FixedWindow::new(171);
/// assert_eq!(p.initial(), 171);
/// assert_eq!(p.next(171, Some(10.0), Some(1.0)), 171);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FixedWindow {
    length: usize,
}

impl FixedWindow {
    /// A fixed window of `length` samples (callers validate `length ≥ 3`; see [`crate::params`]).
    pub fn new(length: usize) -> Self {
        FixedWindow { length }
    }
}

impl WindowPolicy for FixedWindow {
    fn name(&self) -> &'static str {
        "fixed"
    }

    fn bounds(&self) -> WindowBounds {
        WindowBounds {
            min: self.length,
            max: self.length,
        }
    }

    fn initial(&self) -> usize {
        self.length
    }

    fn next(&mut self, _w: usize, _f: Option<f64>, _f_target: Option<f64>) -> usize {
        self.length
    }
}

//! Allan-family estimators, τ grids, and their statistics (EDF, confidence intervals).
//!
//! Every estimator returns [`AllanPoint`]s: the variance at one averaging factor together with the
//! number of terms it averaged, its equivalent degrees of freedom and a χ² confidence interval.
//! The fit weights and "where the model fails" stand on those numbers, so no estimate travels
//! without them.
//!
//! [`naive`] implements the definitions literally and is the oracle for every fast or streaming path.

mod grid;
pub mod naive;

pub use grid::{TauGrid, TauGridError};

use serde::{Deserialize, Serialize};

/// One Allan-family estimate at averaging factor `m`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AllanPoint {
    /// Averaging factor, samples.
    pub m: usize,
    /// τ = m·τ0, seconds.
    pub tau: f64,
    /// The variance estimate σ²(τ) (square it back from a deviation only in reports).
    pub avar: f64,
    /// Number of squared differences that were averaged.
    pub terms: usize,
    /// Equivalent degrees of freedom of `avar`.
    pub edf: f64,
    /// Lower end of the confidence interval of `avar`.
    pub ci_low: f64,
    /// Upper end of the confidence interval of `avar`.
    pub ci_high: f64,
}

impl AllanPoint {
    /// The deviation σ(τ).
    pub fn adev(&self) -> f64 {
        self.avar.sqrt()
    }
}

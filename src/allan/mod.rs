//! Allan-family estimators, τ grids, and their statistics (EDF, confidence intervals).
//!
//! Every estimator returns [`AllanPoint`]s: the variance at one averaging factor together with the
//! number of terms it averaged, its equivalent degrees of freedom and a χ² confidence interval.
//! The fit weights and "where the model fails" stand on those numbers, so no estimate travels
//! without them.
//!
//! The flow: phase (or rate, integrated to phase) → [`fast`] variance per averaging factor →
//! [`noise_id`] α per factor → [`edf`] (Greenhall) → χ² interval. [`estimate`] runs it on a whole
//! phase record (Stable32's tables), [`oavar_rate`] on IMU rate data with NaN marking bad samples,
//! and [`streaming::OavarAccumulator`] sample by sample for the live node.
//!
//! [`naive`] implements the definitions literally and is the oracle for every fast or streaming path.

pub mod edf;
pub mod fast;
mod grid;
pub mod naive;
pub mod noise_id;
mod rate;
pub mod streaming;

pub use grid::{TauGrid, TauGridError};
pub use rate::{
    oavar_rate, oavar_rate_bridged, oavar_rate_bridged_in, oavar_rate_bridged_variances_in, oavar_rate_counted,
    oavar_rate_variances_with_spans_in, RatePoint, BRIDGE_MAX_MISSING,
};

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

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

/// Which Allan-family variance to compute (`--estimator` names: `oadev`, `adev`, `mdev`, `hdev`).
///
/// The overlapping Allan variance is the default and the one the rest of fdavar uses; the others
/// are there to cross-check (MDEV separates white from flicker phase noise, HDEV is blind to a
/// linear frequency drift, which tells a ramp from a random walk).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Estimator {
    /// Overlapping Allan variance (Stable32 "Overlapping Allan").
    #[default]
    Oadev,
    /// Non-overlapping Allan variance (Stable32 "Allan").
    Adev,
    /// Modified Allan variance (Stable32 "Modified Allan").
    Mdev,
    /// Non-overlapping Hadamard variance (Stable32 "Hadamard").
    Hdev,
}

impl Estimator {
    /// All estimators, in `--help` order.
    pub const ALL: [Estimator; 4] = [
        Estimator::Oadev,
        Estimator::Adev,
        Estimator::Mdev,
        Estimator::Hdev,
    ];

    /// The command-line name, e.g. `oadev`.
    pub fn name(self) -> &'static str {
        match self {
            Estimator::Oadev => "oadev",
            Estimator::Adev => "adev",
            Estimator::Mdev => "mdev",
            Estimator::Hdev => "hdev",
        }
    }

    /// Stable32's name for the sigma type, e.g. `Overlapping Allan`.
    pub fn long_name(self) -> &'static str {
        match self {
            Estimator::Oadev => "Overlapping Allan",
            Estimator::Adev => "Allan",
            Estimator::Mdev => "Modified Allan",
            Estimator::Hdev => "Hadamard",
        }
    }

    /// The variance and its number of terms at factor `m` of phase `x`, `None` if `x` is too short.
    pub fn variance(self, x: &[f64], tau0: f64, m: usize) -> Option<(f64, usize)> {
        match self {
            Estimator::Oadev => fast::oavar(x, tau0, m),
            Estimator::Adev => fast::avar(x, tau0, m),
            Estimator::Mdev => fast::mvar(x, tau0, m),
            Estimator::Hdev => fast::hvar(x, tau0, m),
        }
    }

    /// How many multiples of m one term spans in phase points (2 for ADEV/OADEV, 3 for MDEV/HDEV).
    pub fn span(self) -> usize {
        match self {
            Estimator::Oadev | Estimator::Adev => 2,
            Estimator::Mdev | Estimator::Hdev => 3,
        }
    }

    /// The largest averaging factor the estimator can use on `len` phase points.
    pub fn max_factor(self, len: usize) -> usize {
        len.saturating_sub(1) / self.span()
    }

    /// The estimator's shape for Greenhall's EDF.
    pub fn shape(self) -> edf::VarianceShape {
        let (d, overlapping, modified) = match self {
            Estimator::Oadev => (2, true, false),
            Estimator::Adev => (2, false, false),
            Estimator::Mdev => (2, true, true),
            Estimator::Hdev => (3, false, false),
        };
        edf::VarianceShape {
            d,
            overlapping,
            modified,
        }
    }
}

impl fmt::Display for Estimator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An estimator name that is not one of `oadev`, `adev`, `mdev`, `hdev`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown estimator '{0}' (expected oadev, adev, mdev or hdev)")]
pub struct UnknownEstimator(pub String);

impl FromStr for Estimator {
    type Err = UnknownEstimator;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Estimator::ALL
            .into_iter()
            .find(|e| e.name() == s)
            .ok_or_else(|| UnknownEstimator(s.to_string()))
    }
}

/// Why a whole-record estimate could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AllanError {
    /// τ0 must be a positive, finite number of seconds.
    #[error("sample period tau0 = {0} s is not positive and finite")]
    BadTau0(f64),
    /// The confidence level must lie strictly between 0 and 1.
    #[error("confidence level {0} is not strictly between 0 and 1")]
    BadConfidence(f64),
    /// Not even the smallest averaging factor fits in the record.
    #[error("{estimator} needs at least {needed} phase points, got {got}")]
    TooFewPoints {
        /// The estimator asked for.
        estimator: Estimator,
        /// Phase points it needs for m = 1.
        needed: usize,
        /// Phase points given.
        got: usize,
    },
    /// A phase value is NaN or infinite (use [`oavar_rate`] for data with invalid samples).
    #[error("phase value {index} is not finite ({value})")]
    NonFinite {
        /// Zero-based index of the value.
        index: usize,
        /// The value.
        value: f64,
    },
}

/// One estimate with how its EDF was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    /// The estimate, its EDF and its confidence interval.
    pub point: AllanPoint,
    /// The identified power-law exponent α (S_y ∝ f^α), `None` if it could not be identified.
    pub alpha: Option<i32>,
}

/// Estimates `estimator` on a whole phase record at each averaging factor, with EDF and interval.
///
/// This is the Stable32-equivalent batch path: for each factor of `factors` that fits the record
/// (others are left out), the variance, the noise type α identified at that factor
/// ([`noise_id::identify`]), Greenhall's EDF ([`edf::greenhall_edf`]) and the χ² interval at
/// `confidence`. When α cannot be identified (too little data) the EDF falls back to white FM
/// (α = 0, the white rate noise that dominates IMU data), and `alpha` is reported as `None`.
///
/// # Errors
/// [`AllanError::BadTau0`], [`AllanError::BadConfidence`], [`AllanError::NonFinite`], and
/// [`AllanError::TooFewPoints`] when not even m = 1 fits.
///
/// ```
/// use fdavar::allan::{estimate, Estimator};
/// // NBS-14 (NIST SP 1065): OADEV(τ = 2) = 85.95287.
/// let x = [0.0, 103.11111, 123.22222, 157.33333, 166.44444, 48.55555, -96.33333, -2.22222, 111.88889, 0.0];
/// let e = estimate(Estimator::Oadev, &x, 1.0, &[1, 2], fdavar::allan::edf::ONE_SIGMA).unwrap();
/// assert!((e[1].point.adev() - 85.95287).abs() < 1e-4);
/// assert!(e[1].point.ci_low < e[1].point.avar && e[1].point.avar < e[1].point.ci_high);
/// ```
pub fn estimate(
    estimator: Estimator,
    x: &[f64],
    tau0: f64,
    factors: &[usize],
    confidence: f64,
) -> Result<Vec<Estimate>, AllanError> {
    if !(tau0.is_finite() && tau0 > 0.0) {
        return Err(AllanError::BadTau0(tau0));
    }
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(AllanError::BadConfidence(confidence));
    }
    if let Some((index, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(AllanError::NonFinite { index, value });
    }
    if estimator.max_factor(x.len()) == 0 {
        return Err(AllanError::TooFewPoints {
            estimator,
            needed: estimator.span() + 1,
            got: x.len(),
        });
    }
    let shape = estimator.shape();
    Ok(factors
        .iter()
        .filter_map(|&m| {
            let (avar, terms) = estimator.variance(x, tau0, m)?;
            let alpha = noise_id::identify(x, m, shape.d, terms).map(|(a, _)| a);
            Some(Estimate {
                point: with_confidence(
                    m,
                    m as f64 * tau0,
                    avar,
                    terms,
                    alpha.unwrap_or(0),
                    shape,
                    x.len(),
                    confidence,
                ),
                alpha,
            })
        })
        .collect())
}

/// Builds an [`AllanPoint`] with Greenhall's EDF for `alpha` on `n` phase points and its χ² interval.
///
/// When the EDF is undefined (a noise too red for the estimator) the EDF is the number of terms
/// minus one clamped to at least 1 — the white-noise count — and documented as such.
#[allow(clippy::too_many_arguments)]
pub(crate) fn with_confidence(
    m: usize,
    tau: f64,
    avar: f64,
    terms: usize,
    alpha: i32,
    shape: edf::VarianceShape,
    n: usize,
    confidence: f64,
) -> AllanPoint {
    let edf = edf::greenhall_edf(alpha, shape, m, n).unwrap_or((terms as f64 - 1.0).max(1.0));
    let (ci_low, ci_high) =
        edf::chi2_interval(avar, edf, confidence).unwrap_or((f64::NAN, f64::NAN));
    AllanPoint {
        m,
        tau,
        avar,
        terms,
        edf,
        ci_low,
        ci_high,
    }
}

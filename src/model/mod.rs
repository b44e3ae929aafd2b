//! The noise model: effects, the fit to the measured Allan variance, and the diagnosis.
//!
//! The flow: a [`ModelSpec`] (what the user asked for) is resolved through [`effects::REGISTRY`];
//! [`fit::fit`] estimates its time-domain effects on the rate ([`timedomain`]), removes them,
//! measures the whole-record Allan variance ([`measure`]) and fits the stationary effects by
//! weighted non-negative least squares ([`nnls`]); [`diagnose::diagnose`] refits with each effect
//! the model lacks and keeps the gains that pay for their parameters.
//! [`record`] lays bag samples out for the fitter; [`output`] is the JSON of docs/design.md §7 and the
//! figures' data.

pub mod diagnose;
pub mod effects;
pub mod fit;
pub mod measure;
pub mod nnls;
pub mod output;
pub mod record;
pub mod spec;
pub mod timedomain;

pub use diagnose::{diagnose, Diagnosis, Suggestion};
pub use fit::{fit, fit_curve, AxisInput, FitError, FitOptions, FittedModel, Span};
pub use spec::{ModelSpec, SpecError};

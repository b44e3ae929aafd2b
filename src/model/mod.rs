//! The noise model: effects, the fit to the measured Allan variance, and the diagnosis.

pub mod effects;

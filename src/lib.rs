//! fdavar: the noise of an IMU, watched while the robot runs.
//!
//! For each of the six IMU axes fdavar computes the adaptive-window dynamic Allan variance of
//! Yang et al. (2016), "F-DAVAR": a variance ratio F drives the length of the window that cuts the
//! signal, and each window gives one row σ²(t, τ) of the DAVAR surface. The rows are fitted with the
//! IEEE 952 noise terms (Q, N, B, K, R) and the extra physical effects of [`model::effects`], so that
//! a user sees where the model fails and which effect is missing.
//!
//! The data flows through the modules in this order:
//! Imu → [`signal`] (per-axis samples, stamps, gaps) → [`allan`] (estimators, τ grid, EDF) →
//! [`davar`] (F value, window policy, DAVAR row) → [`model`] (fit, diagnosis) → [`report`] / the node.
//! [`bag`] reads and writes rosbag2 recordings, [`sim`] makes recordings whose truth is known, and
//! `ros` (feature `ros`, on by default) is the only module that names ROS 2 client types.
//!
//! # Conventions (stated once, here)
//! - **Units**: SI throughout. Gyro axes are rad/s, accel axes m/s². Display units (°/√h, °/h, …)
//!   exist only in reports.
//! - **Rate and phase**: a rate sample (gyro, accel) is *frequency* data `y[n]`; its running integral
//!   `x[n] = τ0·Σ y[k]` (angle, velocity) is *phase* data. Estimators take either.
//! - **τ and averaging factor**: `τ = m·τ0` with `m` a whole number of samples; τ grids are sets of
//!   unique averaging factors, log-spaced.
//! - **Overlap**: "Allan variance" without qualifier means the fully overlapping estimator (Stable32's
//!   OADEV squared). AVAR is a variance σ²(τ); ADEV is its square root σ(τ). APIs return variances,
//!   reports show deviations.
//! - **Confidence**: every estimate carries its equivalent degrees of freedom (EDF) and a χ² interval
//!   at 68.3 % unless stated.
//! - **Time**: sample times are the sensor's `header.stamp` in nanoseconds; times in specs and reports
//!   are seconds from the first sample of the recording.
//!
//! # References
//! - Yang H., Wang L., Zhu Z., Sun T., "A DAVAR improved algorithm based on adaptive window of σ²
//!   ratio", Electronics Optics & Control 23(10), 2016 (the seed).
//! - Riley W. J., "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008.
//! - IEEE Std 952-1997, Annex C (gyro noise terms).
//! - Galleani L., "The dynamic Allan variance", IEEE TUFFC 56(3), 2009.
#![deny(missing_docs)]

pub mod allan;
pub mod analysis;
pub mod bag;
pub mod davar;
pub mod model;
pub mod msgs;
pub mod params;
pub mod pipeline;
pub mod report;
pub mod results;
pub mod signal;
pub mod sim;

#[cfg(feature = "ros")]
pub mod ros;

//! A seeded simulator of six-axis IMU recordings whose truth is known, built from model::effects.

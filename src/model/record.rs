//! A recording laid out for the fitter: six rate series on a regular grid, temperature aligned.
//!
//! Bag readers and the node hand over [`ImuSample`]s in stamp order, with gaps and duplicates.
//! The fitter wants one rate value per nominal period: a gap becomes NaN samples (so that no Allan
//! term straddles it, DESIGN §1), a duplicate or backwards stamp is dropped and counted, and the
//! temperature is interpolated linearly at each IMU sample time. No I/O here.

use crate::model::fit::AxisInput;
use crate::signal::{nominal_period, Axis, ImuSample, Irregularities, StampCheck, StampClass, TemperatureSample};

/// Six axes of rate samples on a regular grid, with what was irregular.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Nominal period τ0, seconds.
    pub tau0: f64,
    /// Rate samples per axis ([`Axis::ALL`] order); NaN where missing or bad.
    pub axes: [Vec<f64>; 6],
    /// Temperature at each sample, °C, when the recording has a temperature topic.
    pub temperature_c: Option<Vec<f64>>,
    /// Gaps, duplicates, backwards stamps, non-finite values met.
    pub irregularities: Irregularities,
}

/// Why samples cannot be laid out.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    /// Fewer than two distinct stamps: no period.
    #[error("{0} IMU samples: cannot estimate a sample period")]
    NoPeriod(usize),
    /// A gap so long that filling it would exceed the memory bound.
    #[error("a gap of {missing} samples after {at_s:.3} s is longer than the recording allows")]
    HugeGap {
        /// Missing samples.
        missing: u64,
        /// Where, seconds from the first sample.
        at_s: f64,
    },
}

impl Recording {
    /// Lays out samples (in stamp order) and temperature readings on the grid of the nominal period.
    ///
    /// # Errors
    /// [`RecordError::NoPeriod`] with fewer than two distinct stamps; [`RecordError::HugeGap`]
    /// when a gap would more than double the record.
    pub fn from_samples(imu: &[ImuSample], temps: &[TemperatureSample]) -> Result<Self, RecordError> {
        let stamps: Vec<i64> = imu.iter().map(|s| s.stamp_ns).collect();
        let tau0 = nominal_period(&stamps).ok_or(RecordError::NoPeriod(imu.len()))?;
        let mut check = StampCheck::new(tau0);
        let mut axes: [Vec<f64>; 6] = Default::default();
        let mut times: Vec<i64> = Vec::with_capacity(imu.len());
        let t0 = stamps.first().copied().unwrap_or(0);
        for s in imu {
            match check.check(s.stamp_ns) {
                StampClass::Duplicate | StampClass::Backwards => continue,
                StampClass::Gap { missing } => {
                    if missing as usize > imu.len() {
                        return Err(RecordError::HugeGap {
                            missing,
                            at_s: (s.stamp_ns - t0) as f64 * 1e-9,
                        });
                    }
                    for a in axes.iter_mut() {
                        a.extend(std::iter::repeat_n(f64::NAN, missing as usize));
                    }
                    let last = times.last().copied().unwrap_or(t0);
                    for k in 1..=missing as i64 {
                        times.push(last + (k as f64 * tau0 * 1e9) as i64);
                    }
                }
                StampClass::Next => {}
            }
            for (a, v) in axes.iter_mut().zip(s.values()) {
                if !v.is_finite() {
                    check.count_non_finite();
                }
                a.push(v);
            }
            times.push(s.stamp_ns);
        }
        let temperature_c = (!temps.is_empty()).then(|| interpolate(temps, &times));
        Ok(Recording {
            tau0,
            axes,
            temperature_c,
            irregularities: check.counts(),
        })
    }

    /// The fitter's view of one axis (accel axes as g-sensitivity evidence, no DAVAR events).
    pub fn input(&self, axis: Axis) -> AxisInput<'_> {
        AxisInput {
            axis,
            tau0: self.tau0,
            rate: &self.axes[axis.index()],
            temperature_c: self.temperature_c.as_deref(),
            accel: Some([&self.axes[3], &self.axes[4], &self.axes[5]]),
            events: &[],
        }
    }
}

/// Linear interpolation of temperature readings at `times` (held constant beyond the ends).
fn interpolate(temps: &[TemperatureSample], times: &[i64]) -> Vec<f64> {
    let mut sorted: Vec<&TemperatureSample> = temps.iter().filter(|t| t.celsius.is_finite()).collect();
    sorted.sort_by_key(|t| t.stamp_ns);
    let mut k = 0;
    times
        .iter()
        .map(|&t| {
            if sorted.is_empty() {
                return f64::NAN;
            }
            while k + 1 < sorted.len() && sorted[k + 1].stamp_ns <= t {
                k += 1;
            }
            let a = sorted[k];
            match sorted.get(k + 1) {
                Some(b) if t >= a.stamp_ns && b.stamp_ns > a.stamp_ns => {
                    let w = (t - a.stamp_ns) as f64 / (b.stamp_ns - a.stamp_ns) as f64;
                    a.celsius + w * (b.celsius - a.celsius)
                }
                _ => a.celsius,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(stamp_ns: i64, v: f64) -> ImuSample {
        ImuSample { stamp_ns, gyro: [v; 3], accel: [v; 3] }
    }

    #[test]
    fn gaps_become_nan_and_duplicates_are_dropped() {
        let ms = 10_000_000;
        let imu: Vec<ImuSample> = [0, 1, 2, 2, 5, 6]
            .iter()
            .map(|&k| sample(k * ms, k as f64))
            .collect();
        let temps = [
            TemperatureSample { stamp_ns: 0, celsius: 20.0 },
            TemperatureSample { stamp_ns: 6 * ms, celsius: 26.0 },
        ];
        let r = Recording::from_samples(&imu, &temps).unwrap();
        assert!((r.tau0 - 0.01).abs() < 1e-12);
        let x = &r.axes[0];
        assert_eq!(x.len(), 7);
        assert!(x[3].is_nan() && x[4].is_nan() && x[5] == 5.0);
        assert_eq!((r.irregularities.gaps, r.irregularities.duplicates), (1, 1));
        let t = r.temperature_c.unwrap();
        assert!((t[5] - 25.0).abs() < 1e-9 && (t[6] - 26.0).abs() < 1e-9);
    }
}

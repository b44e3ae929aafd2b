//! The node's live temperature coefficient: a regression of block means of each axis's rate on
//! block means of the temperature topic, in O(1) memory.
//!
//! Why block means and not samples: the temperature topic is slow (often 1–10 Hz) and its value
//! changes over minutes, while the rate is fast and noisy; averaging both over the same block of
//! node input turns the pair into one (temperature, rate) point per block whose rate scatter is the
//! white noise divided by √(samples per block). A running least-squares line through those points
//! (Welford-style sums) gives the slope, the coefficient of the `temperature` effect
//! (`coefficient_per_k`, rate unit per kelvin), and its standard error.
//!
//! It is published only when significant: at least [`MIN_BLOCKS`] blocks, a temperature that
//! moved, and |slope| > [`SIGNIFICANCE`]·σ_slope. The standard error assumes independent block
//! residuals; bias instability and random walk make neighbouring blocks correlated, so the
//! threshold is set well above the 2σ of a textbook test.

use crate::model::timedomain::LineFit;
use crate::signal::{Axis, ImuSample, TemperatureSample};

/// Length of a block, ns of IMU stamp time (1 s).
pub const BLOCK_NS: i64 = 1_000_000_000;
/// Blocks needed before a coefficient is published.
pub const MIN_BLOCKS: u64 = 10;
/// |slope| / σ_slope needed to publish.
pub const SIGNIFICANCE: f64 = 5.0;

/// One block being filled: sums of the rates and of the temperatures received meanwhile.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Block {
    index: i64,
    rate_sum: [f64; 6],
    rate_n: u64,
    temp_sum: f64,
    temp_n: u64,
}

/// The live temperature regression of all six axes (see the module doc).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TemperatureRegression {
    origin_ns: Option<i64>,
    block: Option<Block>,
    lines: [LineFit; 6],
}

impl TemperatureRegression {
    /// Adds one checked IMU sample (finite, stamps increasing); closes the block it leaves.
    pub fn push_rate(&mut self, sample: &ImuSample) {
        let origin = *self.origin_ns.get_or_insert(sample.stamp_ns);
        let index = (sample.stamp_ns - origin).div_euclid(BLOCK_NS);
        if self.block.is_some_and(|b| b.index != index) {
            self.close();
        }
        let block = self.block.get_or_insert(Block {
            index,
            rate_sum: [0.0; 6],
            rate_n: 0,
            temp_sum: 0.0,
            temp_n: 0,
        });
        for (sum, v) in block.rate_sum.iter_mut().zip(sample.values()) {
            *sum += v;
        }
        block.rate_n += 1;
    }

    /// Adds one temperature reading to the block open now (a slow topic: its own stamp is not
    /// used to place it; non-finite readings are ignored).
    pub fn push_temperature(&mut self, t: &TemperatureSample) {
        if let (Some(block), true) = (self.block.as_mut(), t.celsius.is_finite()) {
            block.temp_sum += t.celsius;
            block.temp_n += 1;
        }
    }

    fn close(&mut self) {
        let Some(b) = self.block.take() else { return };
        if b.rate_n == 0 || b.temp_n == 0 {
            return;
        }
        let x = b.temp_sum / b.temp_n as f64;
        for (line, sum) in self.lines.iter_mut().zip(b.rate_sum) {
            line.add(x, sum / b.rate_n as f64);
        }
    }

    /// The coefficient of `axis` (rate unit per kelvin) and its standard error, when significant.
    pub fn coefficient(&self, axis: Axis) -> Option<(f64, f64)> {
        let line = &self.lines[axis.index()];
        if line.len() < MIN_BLOCKS {
            return None;
        }
        let (b, sigma) = line.slope()?;
        (b.abs() > SIGNIFICANCE * sigma).then_some((b, sigma))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn a_driven_axis_gets_its_coefficient_and_a_clean_axis_none() {
        // 120 s at 200 Hz, temperature 20 → 40 °C at 2 Hz; gyro_x = 1e-4 rad/s/K·(T − 30) plus
        // white noise 1e-3, gyro_y white noise only (seeded).
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let noise = Normal::new(0.0, 1e-3).unwrap();
        let mut r = TemperatureRegression::default();
        let temp = |k: i64| 20.0 + 20.0 * k as f64 / 24_000.0;
        for k in 0..24_000_i64 {
            let stamp_ns = 1_000_000_000 + k * 5_000_000;
            let sample = ImuSample {
                stamp_ns,
                gyro: [
                    1e-4 * (temp(k) - 30.0) + noise.sample(&mut rng),
                    noise.sample(&mut rng),
                    0.0,
                ],
                accel: [0.0, 0.0, 9.81],
            };
            r.push_rate(&sample);
            if k % 100 == 0 {
                r.push_temperature(&TemperatureSample {
                    stamp_ns,
                    celsius: temp(k),
                });
            }
        }
        let (b, sigma) = r.coefficient(Axis::GyroX).unwrap();
        // σ_b ≈ (1e-3/√200) / (√119 · 5.8 K) ≈ 1.1e-6: 5σ is well inside 10 %.
        assert!((b / 1e-4 - 1.0).abs() < 0.1, "{b} ± {sigma}");
        assert!(r.coefficient(Axis::GyroY).is_none());
        // A constant axis has no slope; a temperature that never moves gives none either.
        assert!(r.coefficient(Axis::GyroZ).is_none());
        let mut flat = TemperatureRegression::default();
        for k in 0..4000_i64 {
            let s = ImuSample {
                stamp_ns: k * 5_000_000,
                gyro: [k as f64, 0.0, 0.0],
                accel: [0.0; 3],
            };
            flat.push_rate(&s);
            flat.push_temperature(&TemperatureSample {
                stamp_ns: s.stamp_ns,
                celsius: 25.0,
            });
        }
        assert!(flat.coefficient(Axis::GyroX).is_none());
    }
}

//! Shared helpers of the model workbench's integration tests: seeded six-axis recordings whose
//! truth is known, generated in memory from the effect kinds (nothing committed to disk).
#![allow(dead_code)]

use fdavar::model::effects::{Effect, SimContext};
use fdavar::model::fit::{AxisInput, Span};
use fdavar::model::testkit;
use fdavar::signal::Axis;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Base noise of a MEMS IMU (D435i-like gyro, with a visible bias instability), SI.
pub const GYRO_NBK: [f64; 3] = [1.5e-4, 5.0e-5, 2.7e-6];
/// Accel base noise, SI (m/s based).
pub const ACCEL_NBK: [f64; 3] = [2.0e-3, 4.0e-4, 1.2e-4];

/// A recording: τ0, six axes of rate samples, optional temperature.
pub struct Recording {
    pub tau0: f64,
    pub axes: [Vec<f64>; 6],
    pub temperature: Option<Vec<f64>>,
}

impl Recording {
    pub fn input(&self, axis: Axis) -> AxisInput<'_> {
        AxisInput {
            axis,
            tau0: self.tau0,
            rate: &self.axes[axis.index()],
            temperature_c: self.temperature.as_deref(),
            accel: Some([&self.axes[3], &self.axes[4], &self.axes[5]]),
            events: &[] as &[Span],
        }
    }
}

/// The base terms N, B, K of an axis.
pub fn base(nbk: [f64; 3]) -> Vec<Box<dyn Effect>> {
    vec![
        testkit::effect("N", &[nbk[0]]),
        testkit::effect("B", &[nbk[1]]),
        testkit::effect("K", &[nbk[2]]),
    ]
}

/// A warm-up temperature profile: 20 °C rising by `rise` K with a 10-minute time constant,
/// plus a slow 0.5 K wobble.
pub fn warmup(n: usize, tau0: f64, rise: f64) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let t = i as f64 * tau0;
            20.0 + rise * (1.0 - (-t / 600.0).exp()) + 0.5 * (t / 300.0).sin()
        })
        .collect()
}

/// Simulates six axes at `rate_hz` for `minutes`; `extra` adds effects to one axis.
///
/// Gyro axes are simulated after the accel axes so that a `g_sensitivity` effect can read them.
pub fn recording(
    seed: u64,
    rate_hz: f64,
    minutes: f64,
    extra: &[(Axis, Vec<Box<dyn Effect>>)],
) -> Recording {
    let tau0 = 1.0 / rate_hz;
    let n = (minutes * 60.0 * rate_hz).round() as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let temperature = warmup(n, tau0, 8.0);
    let mut axes: [Vec<f64>; 6] = Default::default();
    let order = [Axis::AccelX, Axis::AccelY, Axis::AccelZ, Axis::GyroX, Axis::GyroY, Axis::GyroZ];
    for axis in order {
        let nbk = if axis.is_gyro() { GYRO_NBK } else { ACCEL_NBK };
        let mut effects = base(nbk);
        let mut q = None;
        for (a, extra) in extra {
            if *a == axis {
                for e in extra {
                    // Quantization rounds what is there, so it goes last.
                    if e.kind().id() == "quantization" {
                        q = Some(e);
                    } else {
                        effects.push(testkit::effect(e.kind().id(), &values(&**e)));
                    }
                }
            }
        }
        let white_sigma = effects
            .iter()
            .find(|e| e.kind().id() == "white")
            .map(|e| e.params()[0].value / tau0.sqrt())
            .unwrap_or(0.0);
        let accel = [&axes[3][..], &axes[4][..], &axes[5][..]];
        let ctx = SimContext {
            dt: tau0,
            white_sigma,
            temperature_c: Some(&temperature),
            accel: if axis.is_gyro() { Some(accel) } else { None },
        };
        let mut out = testkit::simulate(&effects, &ctx, &mut rng, n);
        if let Some(q) = q {
            q.simulate(&ctx, &mut rng, &mut out);
        }
        axes[axis.index()] = out;
    }
    Recording { tau0, axes, temperature: Some(temperature) }
}

pub fn values(e: &dyn Effect) -> Vec<f64> {
    e.params().iter().map(|p| p.value).collect()
}

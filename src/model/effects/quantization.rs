//! `quantization` (Q): angle quantization, the rounding of the sensor's output.

use super::{
    check_params, params_of, Domain, Effect, EffectKind, Evidence, Explanation, KindInfo, Param,
    OutputContext, ParamError, ParamSpec, SimContext, SimStage,
};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[ParamSpec {
    name: "q",
    unit: "rad",
    bounds: (0.0, 10.0),
    doc: "angle quantization noise Q (rms of the angle rounding error)",
}];

/// The effect id (**contract** name) of this file's effect: `quantization`.
pub const ID: &str = "quantization";

/// The registry entry of [`Quantization`].
pub(super) static KIND: KindInfo = KindInfo {
    id: ID,
    alias: Some("Q"),
    schema: SCHEMA,
    domain: Domain::Spectral,
    evidence: Evidence::None,
    stage: SimStage::Output,
    construct: |v| Ok(Box::new(Quantization::new(v[0])?)),
};

/// Angle quantization noise `q`: the sensor reports its output in whole LSBs.
///
/// A digital gyro counts angle increments (or rounds its rate output to an LSB Δ while carrying
/// the remainder to the next sample), so the *angle* it reports is rounded to a step δ = Δ·τ0. The
/// rounding error of the angle is uniform on ±δ/2 and, once the other noise moves the angle by more
/// than δ per sample, independent from sample to sample: white phase noise, seen at short τ.
///
/// # Formula
/// ```text
/// σ²(τ) = 3·q² / τ²
/// q = δ / √12 = Δ·τ0 / √12        Δ = q·√12 / τ0
/// simulated: s[n] = round(Σ_{k≤n} y[k] / Δ),  y_out[n] = Δ·(s[n] − s[n−1])
/// ```
/// where y is the sum of the axis's other effects (rate), Δ the rate LSB, τ0 the sample period and
/// δ the angle step. Every output value is a whole multiple of Δ and the angle Σ y_out·τ0 is the true
/// angle rounded to δ, so its error `e[n]` has variance q² and `σ²(τ) = E[(e[i+2m] − 2e[i+m] + e[i])²] /
/// (2τ²)` = 6q²/(2τ²). Rounding each rate sample on its own (no carry) was rejected: its error is
/// white *rate* noise of variance Δ²/12, an N term (σ² ∝ 1/τ), not the Q term.
///
/// # References
/// IEEE Std 952-1997, Annex C.1 (quantization noise); Riley, NIST SP 1065, 2008, Table 5 (white PM).
///
/// ```
/// use fdavar::model::effects::{Effect, Quantization};
/// let q = Quantization::new(1e-4).unwrap();
/// assert!((q.avar(0.1).unwrap() - 3e-6).abs() < 1e-18);
/// assert!((q.lsb(0.01) - 1e-4 * 12f64.sqrt() / 0.01).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantization {
    q: f64,
}

impl Quantization {
    /// Builds the effect from the angle quantization `q` in rad.
    ///
    /// # Errors
    /// [`ParamError`] naming `q` when it is NaN or outside [0, 10].
    pub fn new(q: f64) -> Result<Self, ParamError> {
        check_params(KIND.id, SCHEMA, &[q])?;
        Ok(Self { q })
    }

    /// The angle quantization Q, rad.
    pub fn q(&self) -> f64 {
        self.q
    }

    /// The rate LSB Δ = q·√12 / τ0 that gives this Q at sample period `dt`.
    pub fn lsb(&self, dt: f64) -> f64 {
        self.q * 12f64.sqrt() / dt
    }

    /// σ²(τ) of this quantizer when the other noise does not dither it (the undithered signature).
    ///
    /// The IEEE law 3q²/τ² ([`Effect::avar`]) assumes the angle rounding error is white, which
    /// holds only when the other noise moves the angle by about a step δ per sample or more. A
    /// visible quantization is always (partly) undithered: white noise that moves the angle ≥ 1 LSB
    /// per sample has N²/τ ≥ 12q²/(τ·τ0), above 3q²/τ² at every τ ≥ τ0. So the fitter uses this
    /// signature, which covers both regimes: it tends to 3q²/τ² when the angle noise over τ spans
    /// many steps, and is smaller (weaker at short τ) when it does not.
    ///
    /// # Formula
    /// ```text
    /// x = δ·round(θ/δ)                            reported angle, θ the true angle, δ = q·√12
    /// D_x(τ) = D_θ(τ) + δ²·h(τ)                   angle structure function, D(τ) = E[(x(t+τ) − x(t))²]
    /// h(τ) = E[f·(1 − f)],  f = frac(d),  d = (θ(t+τ) − θ(t))/δ ~ N(μ, v)
    /// μ = mean_rate·τ/δ,    v = noise(τ)/δ²
    /// σ²(τ) = (4·D(τ) − D(2τ)) / (2τ²)            any process with stationary increments
    /// σ²_Q(τ) = δ²·(4h(τ) − h(2τ)) / (2τ²) = 6q²·(4h(τ) − h(2τ)) / τ²
    /// ```
    /// where `noise(τ)` is the structure function D_θ(τ) of the other noise on the angle (rad²; for
    /// white rate noise N exactly N²·τ, in general about τ²·σ²_other(τ)) and `mean_rate` the mean of
    /// the rate samples (gravity on an accel axis sweeps the angle through many steps per sample).
    /// The first line of the derivation: with the phase u = frac(θ/δ) uniform and independent of the
    /// increment d = n + f (n whole), round(u + d) − round(u) = n + B with B ~ Bernoulli(f), whose
    /// mean square is d² + f(1 − f). h is computed by [`rounding_excess`]; with h = 1/6 (v ≫ 1) the
    /// formula is the IEEE law 3q²/τ².
    ///
    /// # References
    /// IEEE Std 952-1997, Annex C.1 (the white limit); Riley, NIST SP 1065, 2008, §5.2.2 (AVAR from
    /// the structure function of the phase). The undithered form is derived here (docs/model.md).
    ///
    /// ```
    /// use fdavar::model::effects::{Effect, Quantization};
    /// let q = Quantization::new(1e-4).unwrap();
    /// // Heavy dither (angle noise of 30 steps over τ): the IEEE law.
    /// let white = |tau: f64| (30.0 * 1e-4 * 12f64.sqrt()).powi(2) * tau / 0.01;
    /// let s = q.avar_undithered(0.01, 0.0, &white);
    /// assert!((s / q.avar(0.01).unwrap() - 1.0).abs() < 1e-12);
    /// // No dither and no drift: the reported angle never moves, nothing is seen.
    /// assert_eq!(q.avar_undithered(0.01, 0.0, &|_| 0.0), 0.0);
    /// ```
    pub fn avar_undithered(&self, tau: f64, mean_rate: f64, noise: &dyn Fn(f64) -> f64) -> f64 {
        let step = self.q * 12f64.sqrt();
        if step <= 0.0 || tau.is_nan() || tau <= 0.0 {
            return 0.0;
        }
        let h = |t: f64| rounding_excess(mean_rate * t / step, noise(t).max(0.0) / (step * step));
        6.0 * self.q * self.q * (4.0 * h(tau) - h(2.0 * tau)) / (tau * tau)
    }
}

/// The mean excess E[f·(1 − f)], f = frac(d), of a rounded increment d ~ N(`mu`, `v`) in steps.
///
/// `E[(round(u + d) − round(u))²] = E[d²] + E[f·(1 − f)]` for a uniform phase u: this is the term
/// the rounding adds to the structure function of the angle (see
/// [`Quantization::avar_undithered`]). It is 1/6 when d spreads over many steps (white rounding)
/// and ≈ √(2v/π) − v when μ = 0 and v ≪ 1 (the rounded angle rarely moves).
///
/// # Formula
/// ```text
/// Fourier series (v ≥ 0.02):  h = 1/6 − Σ_{k≥1} cos(2πkμ)·exp(−2π²k²v) / (π²k²)
/// direct sum     (v < 0.02):  h = Σ_n ∫_{n}^{n+1} (x − n)(n + 1 − x)·φ((x − μ)/σ)/σ dx
///                per interval, y = x − μ ∈ [a, b]:  −M2 + (a + b)·M1 − a·b·M0
///                M0 = Φ(β) − Φ(α),  M1 = σ(φ(α) − φ(β)),  M2 = σ²(M0 + αφ(α) − βφ(β))
/// ```
/// where σ = √v, a = n − μ, b = n + 1 − μ, α = a/σ, β = b/σ, φ and Φ the standard normal density
/// and distribution. The series converges fast for large v (10 terms at v = 0.02), the direct sum
/// for small v (the intervals within 10σ of μ); they agree to 1e-12 at the switch.
///
/// ```
/// use fdavar::model::effects::rounding_excess;
/// assert!((rounding_excess(0.3, 50.0) - 1.0 / 6.0).abs() < 1e-15);
/// assert!((rounding_excess(0.25, 0.0) - 0.1875).abs() < 1e-15);
/// let v: f64 = 1e-4;
/// let small = (2.0 * v / std::f64::consts::PI).sqrt() - v;
/// assert!((rounding_excess(0.0, v) - small).abs() < 1e-12);
/// ```
pub fn rounding_excess(mu: f64, v: f64) -> f64 {
    use std::f64::consts::PI;
    let mu = mu - mu.floor();
    if v.is_nan() || v <= 0.0 || !mu.is_finite() {
        return if mu.is_finite() { mu * (1.0 - mu) } else { 1.0 / 6.0 };
    }
    if v >= SERIES_FROM_V {
        let mut sum = 0.0;
        for k in 1..=MAX_SERIES_TERMS {
            let kf = k as f64;
            let decay = (-2.0 * PI * PI * kf * kf * v).exp();
            if decay < 1e-18 {
                break;
            }
            sum += (2.0 * PI * kf * mu).cos() * decay / (PI * PI * kf * kf);
        }
        return 1.0 / 6.0 - sum;
    }
    let sigma = v.sqrt();
    let pdf = |z: f64| (-0.5 * z * z).exp() / (2.0 * PI).sqrt();
    let cdf = |z: f64| 0.5 * statrs::function::erf::erfc(-z / std::f64::consts::SQRT_2);
    let first = (mu - 10.0 * sigma).floor() as i64;
    let last = (mu + 10.0 * sigma).ceil() as i64;
    (first..last)
        .map(|n| {
            let (a, b) = (n as f64 - mu, n as f64 + 1.0 - mu);
            let (al, be) = (a / sigma, b / sigma);
            let m0 = cdf(be) - cdf(al);
            let m1 = sigma * (pdf(al) - pdf(be));
            let m2 = v * (m0 + al * pdf(al) - be * pdf(be));
            -m2 + (a + b) * m1 - a * b * m0
        })
        .sum::<f64>()
        .max(0.0)
}

/// Variance (in steps²) from which [`rounding_excess`] sums the Fourier series.
const SERIES_FROM_V: f64 = 0.02;
/// Upper bound on the series terms (reached only below `SERIES_FROM_V`, which never happens).
const MAX_SERIES_TERMS: usize = 64;

impl Effect for Quantization {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.q])
    }
    fn avar(&self, tau: f64) -> Option<f64> {
        Some(3.0 * self.q * self.q / (tau * tau))
    }
    fn avar_on(&self, tau: f64, rest: &OutputContext<'_>) -> Option<f64> {
        Some(self.avar_undithered(tau, rest.mean_rate, rest.noise))
    }
    fn simulate(&self, ctx: &SimContext<'_>, _rng: &mut dyn RngCore, out: &mut [f64]) {
        let lsb = self.lsb(ctx.dt);
        if lsb <= 0.0 {
            return;
        }
        let mut angle_lsb = 0.0; // true angle so far, in steps δ
        let mut reported = 0.0; // rounded angle reported so far, in steps δ
        for y in out.iter_mut() {
            angle_lsb += *y / lsb;
            let now = angle_lsb.round();
            *y = lsb * (now - reported);
            reported = now;
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "angle quantization of {:.3e} rms: the sensor reports whole output steps, so its \
                 integrated output carries a rounding error that dominates the shortest averaging times",
                self.q
            ),
            avar_slope: Some(-2.0),
            reference: "IEEE Std 952-1997 Annex C.1",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::std_normal;
    use rand::SeedableRng;

    #[test]
    fn output_is_whole_lsbs_and_the_angle_error_stays_within_half_a_step() {
        // The defining property, exactly: every output is a multiple of Δ, and the reported angle
        // Σ y_out·τ0 never differs from the true angle Σ y·τ0 by more than δ/2 = Δ·τ0/2.
        let dt = 0.005;
        let q = Quantization::new(3e-5).unwrap();
        let lsb = q.lsb(dt);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let y: Vec<f64> = (0..5000)
            .map(|_| 0.7 * lsb * std_normal(&mut rng) + 0.1)
            .collect();
        let mut out = y.clone();
        let ctx = SimContext {
            dt,
            white_sigma: 0.0,
            temperature_c: None,
            accel: None,
        };
        q.simulate(&ctx, &mut rng, &mut out);
        let (mut truth, mut reported) = (0.0, 0.0);
        for (a, b) in y.iter().zip(&out) {
            assert!(
                (b / lsb - (b / lsb).round()).abs() < 1e-9,
                "{b} is not whole LSBs"
            );
            truth += a * dt;
            reported += b * dt;
            assert!((truth - reported).abs() <= 0.5 * lsb * dt * (1.0 + 1e-9));
        }
    }

    /// E[f(1 − f)] by brute-force quadrature of the Gaussian (Simpson on ±12σ, 20 000 panels).
    fn excess_by_quadrature(mu: f64, v: f64) -> f64 {
        let s = v.sqrt();
        let (lo, hi, n) = (mu - 12.0 * s, mu + 12.0 * s, 20_000);
        let h = (hi - lo) / n as f64;
        let g = |x: f64| {
            let f = x - x.floor();
            f * (1.0 - f) * (-0.5 * ((x - mu) / s).powi(2)).exp() / (s * (2.0 * std::f64::consts::PI).sqrt())
        };
        (0..=n)
            .map(|i| {
                let w = if i == 0 || i == n { 1.0 } else if i % 2 == 1 { 4.0 } else { 2.0 };
                w * g(lo + h * i as f64)
            })
            .sum::<f64>()
            * h
            / 3.0
    }

    #[test]
    fn rounding_excess_matches_quadrature_on_both_sides_of_the_switch() {
        for &v in &[1e-5, 1e-3, 0.01, 0.0199, 0.02, 0.05, 0.3, 2.0] {
            for &mu in &[0.0, 0.1, 0.37, 0.5, 0.93, 70.6, -3.25] {
                let (got, want) = (rounding_excess(mu, v), excess_by_quadrature(mu, v));
                // Simpson's error on a kinked integrand: O(h²) at the kinks, h = 24σ/20000.
                assert!((got - want).abs() < 1e-7, "mu {mu} v {v}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn series_and_direct_sum_agree_at_the_switch() {
        for &mu in &[0.0, 0.2, 0.5, 0.8] {
            let v = SERIES_FROM_V;
            let series = rounding_excess(mu, v);
            let direct = rounding_excess(mu, v * (1.0 - 1e-12));
            assert!((series - direct).abs() < 1e-11, "mu {mu}: {series} vs {direct}");
        }
    }

    #[test]
    fn undithered_signature_is_weaker_than_ieee_and_tends_to_it() {
        // White angle noise of r steps per sample at τ0 = 0.01 s.
        let (q, dt) = (Quantization::new(3e-5).unwrap(), 0.01);
        let step = 3e-5 * 12f64.sqrt();
        let mut last = 0.0;
        for r in [0.05, 0.1, 0.2, 0.5, 1.0, 3.0] {
            let noise = move |tau: f64| (r * step).powi(2) * tau / dt;
            let ratio = q.avar_undithered(dt, 0.0, &noise) / q.avar(dt).unwrap();
            assert!(ratio > last && ratio <= 1.0 + 1e-12, "r {r}: ratio {ratio}");
            last = ratio;
        }
        assert!((last - 1.0).abs() < 1e-9);
    }
}

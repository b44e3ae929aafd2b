//! The exponentially correlated (Ornstein–Uhlenbeck) process that two effects are: `gauss_markov`
//! (a bias that wanders and is pulled back) and `bandwidth` (white noise through a first-order
//! low-pass). One process, two explanations: its Allan variance and its simulation live here once.

use super::std_normal;
use rand::RngCore;

/// Where the two explanations meet, in units of the shortest τ of the fit: a process whose time
/// constant is shorter than this many τmin is the sensor's filter (`bandwidth`, searched up to it),
/// a longer one a bias that wanders (`gauss_markov`, searched from it).
///
/// Why 2 and not 1: within two sample periods the process has decorrelated before the Allan
/// variance can show a rise like a random walk, so nothing on the τ grid tells a bias from a
/// filter there. With the meeting point at τmin, a Gauss–Markov term of T just above it took a
/// low-pass sensor's white noise under the wrong name: on simulated sensors with a 0.3·rate
/// low-pass (`examples/diagnosis_power.rs low-pass 20 1000`) `gauss_markov` came first instead
/// of `bandwidth` on 20 of 20 axes with a hidden quantization and 5 of 20 with a hidden sinusoid.
pub(super) const FILTER_MEMORY_TAUS: f64 = 2.0;

/// The bracket of the Allan variance of the averages over τ of an Ornstein–Uhlenbeck process of
/// time constant T, at x = τ/T.
///
/// # Formula
/// ```text
/// σ²(τ) = q²T²/τ · b(τ/T),   b(x) = 1 − (3 − 4·e^(−x) + e^(−2x))/(2x)
///       ≈ x²/3 − x³/4 + 7x⁴/60 − x⁵/24   for x < 10⁻² (its series: the closed form cancels)
/// ```
/// where q² is the density of the white drive (q²T² = n², the white noise the process becomes
/// for τ ≫ T).
///
/// # References
/// IEEE Std 952-1997, Annex C (exponentially correlated noise).
pub(super) fn allan_bracket(x: f64) -> f64 {
    if x < 1e-2 {
        x * x * (1.0 / 3.0 - x / 4.0 + 7.0 * x * x / 60.0 - x * x * x / 24.0)
    } else {
        1.0 - (3.0 - 4.0 * (-x).exp() + (-2.0 * x).exp()) / (2.0 * x)
    }
}

/// Adds to `out` the means over each period `dt` of a stationary Ornstein–Uhlenbeck process of
/// time constant `t` driven by white noise of density n (`n2` = n²): stationary variance n²/(2T).
///
/// Period means, as an integrating sensor outputs them, make the mean of m samples the average
/// over τ = m·dt, so [`allan_bracket`] is exact on the τ grid.
///
/// # Formula
/// The state x (the process at the end of a period) and the period's mean y = I/dt, I = ∫x dt,
/// with φ = e^(−dt/T), follow
/// ```text
/// x₊ = φ·x + e₁,   I = T(1 − φ)·x + e₂,   (e₁, e₂) ~ N(0, C)
/// C₁₁ = n²(1 − φ²)/(2T),  C₂₂ = n²·[dt − 2T(1 − φ) + T(1 − φ²)/2],  C₁₂ = n²(1 − φ)²/2
/// ```
/// from a stationary start, two standard normal draws per sample.
///
/// # References
/// D. T. Gillespie, "Exact numerical simulation of the Ornstein-Uhlenbeck process and its
/// integral", Phys. Rev. E 54(2), 1996.
pub(super) fn add_period_means(n2: f64, t: f64, dt: f64, rng: &mut dyn RngCore, out: &mut [f64]) {
    let phi = (-dt / t).exp();
    let c11 = n2 * (1.0 - phi * phi) / (2.0 * t);
    let c12 = n2 * (1.0 - phi).powi(2) / 2.0;
    let c22 = n2 * (dt - 2.0 * t * (1.0 - phi) + t * (1.0 - phi * phi) / 2.0);
    // Cholesky of C; C₂₂ − C₁₂²/C₁₁ ≥ 0 up to rounding.
    let l11 = c11.sqrt();
    let l21 = if l11 > 0.0 { c12 / l11 } else { 0.0 };
    let l22 = (c22 - l21 * l21).max(0.0).sqrt();
    let mut x = (n2 / (2.0 * t)).sqrt() * std_normal(rng);
    for y in out.iter_mut() {
        let (u, v) = (std_normal(rng), std_normal(rng));
        let integral = t * (1.0 - phi) * x + l21 * u + l22 * v;
        x = phi * x + l11 * u;
        *y += integral / dt;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_series_joins_the_closed_form() {
        // At the switch both forms agree to the closed form's cancellation error (~1e-16/x²).
        let (below, above) = (allan_bracket(1e-2 * (1.0 - 1e-12)), allan_bracket(1e-2));
        assert!((below / above - 1.0).abs() < 1e-9, "{below} vs {above}");
        // And both tend to x²/3.
        assert!((allan_bracket(1e-4) / (1e-8 / 3.0) - 1.0).abs() < 1e-3);
    }
}

//! Parameter uncertainties: the covariance of the amplitudes and shape parameters from the
//! generalised least-squares normal matrix, with the correlation of Allan estimates between τ
//! points.
//!
//! Overlapping Allan estimates at neighbouring τ share most of their differences. Treating the τ
//! points as independent (the ordinary normal matrix) was rejected: it understated every σ (1σ
//! covered N, B, K 7, 6 and 3 times in 12); see [`tau_correlation`].

use super::solver::{Problem, Solution};
use crate::model::measure::NoiseClass;
use nalgebra::{DMatrix, DVector};

impl Problem<'_> {
    /// Variances of [c_1..c_J, log-shape_1..] from the generalised least-squares normal matrix
    /// Jᵀ·R⁻¹·J at the solution (active amplitudes only), scaled by max(1, χ²/dof), where R is the
    /// correlation of the Allan estimates between τ points ([`tau_correlation`]).
    pub(super) fn covariance(&self, shapes: &[f64], sol: &Solution) -> Option<Vec<Option<f64>>> {
        // An amplitude at its bound (0) still gets the curvature of the cost there: its σ says how
        // large the term could be (reported as √σ_c). Should that make the matrix singular, the
        // bound terms are left out.
        let at_bound = |j: usize| sol.c[j] <= 0.0 && self.columns[j].shapes.is_empty();
        self.covariance_of(shapes, sol, |j| sol.c[j] > 0.0 || at_bound(j))
            .or_else(|| self.covariance_of(shapes, sol, |j| sol.c[j] > 0.0))
    }

    fn covariance_of(
        &self,
        shapes: &[f64],
        sol: &Solution,
        included: impl Fn(usize) -> bool,
    ) -> Option<Vec<Option<f64>>> {
        let k = self.points.len();
        let jn = self.columns.len();
        let sd: Vec<f64> = (0..k)
            .map(|i| sol.model[i].max(f64::MIN_POSITIVE) * (2.0 / sol.edf[i]).sqrt())
            .collect();
        let active: Vec<usize> = (0..jn).filter(|&j| included(j)).collect();
        let mut cols: Vec<Vec<f64>> = active
            .iter()
            .map(|&j| (0..k).map(|i| sol.basis[j][i] / sd[i]).collect())
            .collect();
        let mut index: Vec<usize> = active.clone();
        // Shape derivatives by central differences of the model, at fixed amplitudes.
        let h = 1e-4;
        for d in 0..shapes.len() {
            let mut up = shapes.to_vec();
            let mut dn = shapes.to_vec();
            up[d] += h;
            dn[d] -= h;
            let (bu, bd) = (self.basis(&up).ok()?, self.basis(&dn).ok()?);
            let col: Vec<f64> = (0..k)
                .map(|i| {
                    let mu: f64 = (0..jn).map(|j| sol.c[j] * bu[j][i]).sum();
                    let md: f64 = (0..jn).map(|j| sol.c[j] * bd[j][i]).sum();
                    (mu - md) / (2.0 * h) / sd[i]
                })
                .collect();
            cols.push(col);
            index.push(jn + d);
        }
        if cols.is_empty() {
            return Some(vec![None; jn + shapes.len()]);
        }
        let jac = DMatrix::from_fn(k, cols.len(), |i, c| cols[c][i]);
        let length: Vec<f64> = (0..k)
            .map(|i| {
                let total: f64 = (0..jn).map(|j| sol.c[j] * sol.basis[j][i]).sum();
                let weighted: f64 = (0..jn)
                    .map(|j| sol.c[j] * sol.basis[j][i] * self.columns[j].class.correlation_length())
                    .sum();
                if total > 0.0 {
                    weighted / total
                } else {
                    NoiseClass::WhiteFm.correlation_length()
                }
            })
            .collect();
        let taus: Vec<f64> = self.points.iter().map(|p| p.tau).collect();
        let r = tau_correlation(&taus, &length).cholesky()?;
        let normal = jac.transpose() * r.solve(&jac);
        let inv = normal.try_inverse()?;
        let dof = k.saturating_sub(cols.len()).max(1) as f64;
        // The generalised χ² (zᵀ R⁻¹ z): residuals that do not follow the smooth correlation of
        // the estimates (a misfit) widen the intervals.
        let z = DVector::from_column_slice(&sol.z);
        let chi2_gls = z.dot(&r.solve(&z));
        let scale = (chi2_gls / dof).max(1.0);
        let mut out = vec![None; jn + shapes.len()];
        for (c, &idx) in index.iter().enumerate() {
            let v = inv[(c, c)] * scale;
            if v.is_finite() && v >= 0.0 {
                out[idx] = Some(v);
            }
        }
        Some(out)
    }
}

/// Correlation matrix of overlapping Allan estimates at the τ points `taus`, for a local
/// correlation length `length` in ln τ (per point, from the noise mix:
/// [`NoiseClass::correlation_length`]).
///
/// # Formula
/// ```text
/// uᵢ = Σ_{l<i} ln(τ_{l+1}/τ_l) / (½(ℓ_l + ℓ_{l+1}))
/// Rᵢⱼ = (1 − η)·exp(−(uᵢ − uⱼ)²) + η·δᵢⱼ,     η = 0.01
/// ```
/// For a constant ℓ, ρ = exp(−(ln(τ₂/τ₁)/ℓ)²), the measured correlation of two estimates; warping
/// ln τ by the local ℓ keeps R positive definite (a Gaussian kernel on u) when the noise class
/// changes along the grid. η keeps the matrix invertible on a dense grid (the estimates are not
/// exactly a smooth curve of τ: at τ ratio 1.26 they correlate at 0.91–0.985, not 1). Why it
/// matters: with ten τ per decade the points are far from independent, and treating them as
/// independent understated every uncertainty (1σ covered N, B, K 7, 6 and 3 times in 12).
pub fn tau_correlation(taus: &[f64], length: &[f64]) -> DMatrix<f64> {
    const NUGGET: f64 = 0.01;
    let mut u = vec![0.0; taus.len()];
    for i in 1..taus.len() {
        let step = (taus[i] / taus[i - 1]).ln().abs();
        u[i] = u[i - 1] + step / (0.5 * (length[i] + length[i - 1]));
    }
    DMatrix::from_fn(taus.len(), taus.len(), |i, j| {
        let smooth = (-(u[i] - u[j]).powi(2)).exp();
        (1.0 - NUGGET) * smooth + if i == j { NUGGET } else { 0.0 }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::{find, id};
    use crate::model::fit::exact_points;
    use crate::model::fit::scoring::z_scores;

    #[test]
    fn correlation_of_a_constant_length_is_the_gaussian_in_ln_tau() {
        let l = NoiseClass::WhiteFm.correlation_length();
        let taus = [1.0, 2.0, 8.0];
        let r = tau_correlation(&taus, &[l; 3]);
        let rho = |t2: f64, t1: f64| (-((t2 / t1).ln() / l).powi(2)).exp();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1e-300);
        for i in 0..3 {
            assert!(close(r[(i, i)], 1.0));
            for j in 0..3 {
                assert_eq!(r[(i, j)], r[(j, i)]);
                if i != j {
                    // ρ = exp(−(ln(τ₂/τ₁)/ℓ)²), shrunk by the nugget η = 0.01.
                    assert!(close(r[(i, j)], 0.99 * rho(taus[j], taus[i])), "R[{i}][{j}] = {}", r[(i, j)]);
                }
            }
        }
    }

    #[test]
    fn correlation_warps_ln_tau_by_the_local_length() {
        let taus = [1.0, 2.0, 4.0];
        let l = [0.84, 1.29, 1.97];
        let r = tau_correlation(&taus, &l);
        // u₁ = ln 2/((ℓ₀+ℓ₁)/2), u₂ = u₁ + ln 2/((ℓ₁+ℓ₂)/2).
        let u1 = 2f64.ln() / (0.5 * (l[0] + l[1]));
        let u2 = u1 + 2f64.ln() / (0.5 * (l[1] + l[2]));
        assert!((r[(0, 2)] - 0.99 * (-u2 * u2).exp()).abs() < 1e-12);
        assert!((r[(1, 2)] - 0.99 * (-(u2 - u1).powi(2)).exp()).abs() < 1e-12);
        assert!(r.cholesky().is_some());
    }

    #[test]
    fn correlated_points_widen_the_variance_of_an_amplitude() {
        // One white column at two τ with equal EDF e: J = [j, j], j = 1/(c·√(2/e)), and
        // (Jᵀ R⁻¹ J)⁻¹ = (1 + ρ)·c²/e, where independent points would give c²/e.
        let c = 4e-6;
        let points: Vec<_> = exact_points(|tau| c / tau, 1_000_000).into_iter().take(2).collect();
        let problem = Problem::new(&points, &[find(id::WHITE).unwrap()]).unwrap();
        let basis = problem.basis(&[]).unwrap();
        let meas: Vec<f64> = points.iter().map(|p| p.avar).collect();
        let model: Vec<f64> = basis[0].iter().map(|b| c * b).collect();
        let e = 1000.0;
        let edf = vec![e; 2];
        let z = z_scores(&meas, &model, &edf);
        let sol = Solution { c: vec![c], model, edf, chi2: 0.0, z, cost: 0.0, basis };
        let var = problem.covariance(&[], &sol).unwrap()[0].unwrap();
        let l = NoiseClass::WhiteFm.correlation_length();
        let rho = 0.99 * (-(2f64.ln() / l).powi(2)).exp();
        let want = (1.0 + rho) * c * c / e;
        assert!((var / want - 1.0).abs() < 1e-9, "{var} vs {want}");
    }
}

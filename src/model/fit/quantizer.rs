//! Output columns (a quantizer): effects applied to the sensor's output, whose Allan signature
//! depends on their own amplitude, on the samples' mean and on the other terms, which dither them.
//!
//! Such a column is not linear in its squared amplitude, so the NNLS of `solver` cannot fit it
//! alone. It is settled by a profile search over its amplitude ([`Problem::settle_output_columns`]),
//! holding it fixed at each trial and refitting the others with a Gauss–Newton correction for the
//! dither they give it. Without the samples' mean (a DAVAR row) the column keeps its IEEE law and
//! none of this runs.

use super::scoring::{log_cost, z_scores};
use super::searches::golden_section;
use super::solver::{Problem, Solution};
use super::types::FitError;
use crate::model::effects::{OutputContext, SimStage};

/// Log step of the scan over an output column's amplitude when no mean sweep is visible.
const SCAN_STEP: f64 = 0.02;

/// Most trial amplitudes in one scan (a strong sweep needs ~2000 for [q₀/2, 3q₀]).
const MAX_SCAN: usize = 4000;

/// Dither per sample (steps²) below which the phase of the mean sweep is visible:
/// exp(−2π²·0.7) ≈ 1e-6.
const PHASE_VISIBLE_V: f64 = 0.7;

/// Rounds of "recompute the dither from the other terms, refit them" at each trial amplitude of
/// an output column (the profile over the other amplitudes).
const PROFILE_ROUNDS: usize = 3;

/// The state an output column's signature is computed from.
#[derive(Clone)]
pub(super) struct OutputState {
    /// Mean of the rate samples.
    pub(super) mean_rate: f64,
    /// Squared amplitudes of all columns (the output ones and the others, which dither them).
    pub(super) c: Vec<f64>,
    /// True: the output columns are held at `c` (their curves are a fixed part of the model and
    /// their basis columns are zero); false: they are columns per unit amplitude like the others.
    pub(super) fixed: bool,
    /// While held: ∂(output curves)/∂c_i at `c` for each column i (empty: none), so that a solve
    /// is a Gauss–Newton step on the model's true dependence on the other amplitudes (they
    /// dither the quantizer: with little dither, more white noise *lowers* the quantizer's
    /// short-τ part by about as much as it adds itself).
    pub(super) jacobian: Vec<Vec<f64>>,
}

impl Problem<'_> {
    pub(super) fn is_output(&self, j: usize) -> bool {
        self.columns[j].kind.sim_stage() == SimStage::Output
    }

    /// Column j per unit squared amplitude when it is an output effect with a current state:
    /// zero while the output columns are held fixed (their curves are then [`Problem::offset`]),
    /// otherwise its curve at the state divided by its squared amplitude.
    pub(super) fn output_basis(&self, j: usize, shapes: &[f64]) -> Result<Option<Vec<f64>>, FitError> {
        let Some(state) = self.output.as_ref() else {
            return Ok(None);
        };
        if !self.is_output(j) {
            return Ok(None);
        }
        if state.fixed {
            return Ok(Some(vec![0.0; self.points.len()]));
        }
        if state.c[j] <= 0.0 {
            return Ok(None);
        }
        let curve = self.output_curve(j, shapes, state)?;
        Ok(Some(curve.iter().map(|v| v / state.c[j]).collect()))
    }

    /// σ²(τ) of output column j at the state's amplitudes: its signature given the samples' mean
    /// and the other columns' noise (angle structure function D(τ) ≈ τ²·Σ σ²_other(τ), exact for
    /// white noise, whose dither is the one that matters at short τ).
    fn output_curve(&self, j: usize, shapes: &[f64], state: &OutputState) -> Result<Vec<f64>, FitError> {
        let c = &state.c;
        if c[j] <= 0.0 {
            return Ok(vec![0.0; self.points.len()]);
        }
        let others = (0..self.columns.len())
            .filter(|&i| !self.is_output(i) && c[i] > 0.0)
            .map(|i| self.build(i, c[i].sqrt(), shapes))
            .collect::<Result<Vec<_>, _>>()?;
        let noise = |tau: f64| {
            tau * tau * others.iter().map(|e| e.avar(tau).unwrap_or(0.0).max(0.0)).sum::<f64>()
        };
        let rest = OutputContext { mean_rate: state.mean_rate, noise: &noise };
        let eff = self.build(j, c[j].sqrt(), shapes)?;
        Ok(self
            .points
            .iter()
            .map(|p| eff.avar_on(p.tau, &rest).unwrap_or(0.0).max(0.0))
            .collect())
    }

    /// The part of the model held fixed: the output columns' curves while they are held, less
    /// their linear part in the other amplitudes (which [`Problem::basis`] adds to those columns).
    pub(super) fn offset(&self, shapes: &[f64]) -> Result<Vec<f64>, FitError> {
        let mut sum = vec![0.0; self.points.len()];
        if let Some(state) = self.output.as_ref().filter(|s| s.fixed) {
            sum = self.output_curves(shapes, state)?;
            for (d, c) in state.jacobian.iter().zip(&state.c) {
                for (s, v) in sum.iter_mut().zip(d) {
                    *s -= c * v;
                }
            }
        }
        Ok(sum)
    }

    /// Angle structure function τ²·Σ σ²_i(τ) of the non-output columns at amplitudes √c.
    fn other_noise(&self, shapes: &[f64], c: &[f64], tau: f64) -> Result<f64, FitError> {
        let mut sum = 0.0;
        for i in (0..self.columns.len()).filter(|&i| !self.is_output(i) && c[i] > 0.0) {
            sum += self.build(i, c[i].sqrt(), shapes)?.avar(tau).unwrap_or(0.0).max(0.0);
        }
        Ok(tau * tau * sum)
    }

    /// Σ of the output columns' curves at `state`.
    fn output_curves(&self, shapes: &[f64], state: &OutputState) -> Result<Vec<f64>, FitError> {
        let mut sum = vec![0.0; self.points.len()];
        for j in (0..self.columns.len()).filter(|&j| self.is_output(j)) {
            for (s, v) in sum.iter_mut().zip(self.output_curve(j, shapes, state)?) {
                *s += v;
            }
        }
        Ok(sum)
    }

    /// ∂(output curves)/∂c_i at `state` for every non-output column i, by forward differences of
    /// 5 % of max(c_i, scale_i/100) (zero for a column with no scale).
    fn output_jacobian(&self, shapes: &[f64], state: &OutputState, scale: &[f64]) -> Result<Vec<Vec<f64>>, FitError> {
        let base = self.output_curves(shapes, state)?;
        (0..self.columns.len())
            .map(|i| {
                let h = 0.05 * state.c[i].max(0.01 * scale[i]);
                if self.is_output(i) || h <= 0.0 {
                    return Ok(vec![0.0; self.points.len()]);
                }
                let mut up = state.clone();
                up.c[i] += h;
                let moved = self.output_curves(shapes, &up)?;
                Ok(moved.iter().zip(&base).map(|(a, b)| (a - b) / h).collect())
            })
            .collect()
    }

    /// Fits the output columns (a quantizer), whose signature depends on their own amplitude and
    /// on the other terms (the dither), by a profile search over each one's amplitude q.
    ///
    /// At each trial q the column is held at q² and the other amplitudes are refitted, with the
    /// dither recomputed from them ([`PROFILE_ROUNDS`]); the q of least cost wins (a log scan of
    /// [q₀/2, 3q₀] around the IEEE fit's q₀, then golden section). A plain fixed point (column
    /// from the current fit, refit, repeat) was rejected: it is not the least-squares optimum —
    /// measured, it settled on N = 5.5e-5 instead of 1.5e-4 with q 55 % high on a deeply
    /// undithered gyro, and on the wrong phase of a gravity sweep. The scan step resolves the
    /// phase of a mean sweep: the signature at τ0 changes with frac(mean·τ0/δ), which turns once
    /// per 1/μ₁ in ln q (μ₁ = |mean|·τ0/δ steps per sample). Shape parameters stay those found
    /// with the IEEE columns.
    pub(super) fn settle_output_columns(
        &mut self,
        mean_rate: f64,
        shapes: &[f64],
        sol: Solution,
        iters: usize,
    ) -> Result<Solution, FitError> {
        let outputs: Vec<usize> = (0..self.columns.len()).filter(|&j| self.is_output(j)).collect();
        let mut best_c = sol.c.clone();
        let scale = sol.c.clone();
        let mut best: Option<(f64, Solution)> = None;
        let tau_min = self.points.first().map_or(1.0, |p| p.tau);
        for &j in &outputs {
            let q0 = best_c[j].sqrt();
            if q0 <= 0.0 {
                continue;
            }
            // The phase of the mean sweep matters only while the dither per sample is below a
            // step (exp(−2π²v₁) is its weight); then the scan must resolve 1/μ₁ in ln q.
            let step_max = 3.0 * q0 * 12f64.sqrt();
            let v1 = self.other_noise(shapes, &best_c, tau_min)? / (step_max * step_max);
            let mu1 = mean_rate.abs() * tau_min / (q0 * 12f64.sqrt());
            let step = if v1 < PHASE_VISIBLE_V {
                SCAN_STEP.min(0.06 / mu1.max(1e-9))
            } else {
                SCAN_STEP
            };
            let (mut lo, mut hi) = ((0.5 * q0).ln(), (3.0 * q0).ln());
            let mut start = best_c.clone();
            let mut scan_best = (f64::INFINITY, lo);
            let mut refine_from = best_c.clone();
            // A fine scan moves q by < 1 % a step, so one round from the previous trial's
            // amplitudes follows the others closely enough (the refinement does all rounds).
            let scan_rounds = if step < SCAN_STEP { 1 } else { PROFILE_ROUNDS };
            // Extend the scan upwards while its best is at the top (a deeply undithered
            // quantizer looks far smaller to the IEEE law than it is), at most to 100·q₀.
            for _ in 0..4 {
                let n = (((hi - lo) / step).ceil() as usize).clamp(1, MAX_SCAN);
                for i in 0..=n {
                    let lq = lo + (hi - lo) * i as f64 / n as f64;
                    let (cost, s) = self.profile(j, lq.exp(), &start, &scale, mean_rate, shapes, iters, scan_rounds)?;
                    start = s.c.clone();
                    if cost < scan_best.0 {
                        scan_best = (cost, lq);
                        refine_from.clone_from(&s.c);
                    }
                }
                if scan_best.1 < hi - 1.5 * step || hi > (100.0 * q0).ln() {
                    break;
                }
                (lo, hi) = (hi, hi + 3f64.ln());
            }
            let mid = golden_section(scan_best.1 - step, scan_best.1 + step, 24, |lq| {
                Ok(self.profile(j, lq.exp(), &refine_from, &scale, mean_rate, shapes, iters, PROFILE_ROUNDS)?.0)
            })?;
            let lq = if self.profile(j, mid.exp(), &refine_from, &scale, mean_rate, shapes, iters, PROFILE_ROUNDS)?.0 <= scan_best.0 {
                mid
            } else {
                scan_best.1
            };
            let (cost, s) = self.profile(j, lq.exp(), &refine_from, &scale, mean_rate, shapes, iters, PROFILE_ROUNDS)?;
            best_c = s.c.clone();
            best = Some((cost, s));
        }
        let Some((_, sol)) = best else {
            return Ok(sol);
        };
        // The output columns stay at the winning state (per unit amplitude, like the others), so
        // that the covariance sees the basis the amplitudes came from.
        self.output = Some(OutputState { mean_rate, c: best_c, fixed: false, jacobian: Vec::new() });
        Ok(sol)
    }

    /// The fit with output column j held at amplitude `q` and the others refitted, the dither
    /// recomputed from them each round; returns its cost and the solution (with c[j] = q²).
    #[allow(clippy::too_many_arguments)]
    fn profile(
        &mut self,
        j: usize,
        q: f64,
        start: &[f64],
        scale: &[f64],
        mean_rate: f64,
        shapes: &[f64],
        iters: usize,
        rounds: usize,
    ) -> Result<(f64, Solution), FitError> {
        let mut c = start.to_vec();
        let mut edf = Vec::new();
        for _ in 0..rounds.max(1) {
            c[j] = q * q;
            let mut state = OutputState { mean_rate, c: c.clone(), fixed: true, jacobian: Vec::new() };
            state.jacobian = self.output_jacobian(shapes, &state, scale)?;
            self.output = Some(state);
            let s = self.solve(shapes, iters)?;
            c = s.c.clone();
            edf = s.edf;
        }
        c[j] = q * q;
        // The model as it is at these amplitudes (not its linearisation), and its cost.
        self.output = Some(OutputState { mean_rate, c: c.clone(), fixed: false, jacobian: Vec::new() });
        let basis = self.basis(shapes)?;
        let meas: Vec<f64> = self.points.iter().map(|p| p.avar).collect();
        let model: Vec<f64> = (0..meas.len())
            .map(|i| c.iter().zip(&basis).map(|(cj, b)| cj * b[i]).sum())
            .collect();
        let cost = log_cost(&meas, &model, &edf);
        let z = z_scores(&meas, &model, &edf);
        let chi2 = z.iter().map(|v| v * v).sum();
        let sol = Solution { c, model, edf, z, chi2, cost, basis };
        Ok((if cost.is_finite() { cost } else { f64::MAX }, sol))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::{find, id};
    use crate::model::fit::exact_points;

    fn problem(points: &[crate::allan::AllanPoint]) -> Problem<'_> {
        let kinds = [find(id::QUANTIZATION).unwrap(), find(id::WHITE).unwrap()];
        Problem::new(points, &kinds).unwrap()
    }

    #[test]
    fn only_the_quantizer_is_an_output_column() {
        let points = exact_points(|tau| 1e-6 / tau, 100_000);
        let p = problem(&points);
        assert!(p.is_output(0) && !p.is_output(1));
        // Without an output state the quantizer keeps its IEEE column and nothing is held fixed.
        assert_eq!(p.output_basis(0, &[]).unwrap(), None);
        assert_eq!(p.offset(&[]).unwrap(), vec![0.0; points.len()]);
    }

    #[test]
    fn the_dither_is_the_angle_structure_function_of_the_other_columns() {
        let points = exact_points(|tau| 1e-6 / tau, 100_000);
        let p = problem(&points);
        // c = [q², n²]: the quantizer is left out, white noise gives D(τ) = τ²·n²/τ = n²·τ.
        let n2 = 4e-6;
        for tau in [0.01, 0.1, 1.0] {
            let d = p.other_noise(&[], &[1e-8, n2], tau).unwrap();
            assert!((d / (n2 * tau) - 1.0).abs() < 1e-12, "τ = {tau}: {d}");
        }
    }

    #[test]
    fn a_held_quantizer_has_a_zero_column_and_its_curve_in_the_offset() {
        let points = exact_points(|tau| 1e-6 / tau, 100_000);
        let mut p = problem(&points);
        let c = vec![1e-8, 4e-6];
        let free = OutputState { mean_rate: 0.3, c: c.clone(), fixed: false, jacobian: Vec::new() };
        let curve = p.output_curve(0, &[], &free).unwrap();
        p.output = Some(OutputState { fixed: true, ..free.clone() });
        assert_eq!(p.output_basis(0, &[]).unwrap(), Some(vec![0.0; points.len()]));
        // No Jacobian: the offset is the quantizer's curve itself.
        assert_eq!(p.offset(&[]).unwrap(), curve);
        // Free, the column is that curve per unit squared amplitude.
        p.output = Some(free);
        let per_unit: Vec<f64> = curve.iter().map(|v| v / c[0]).collect();
        assert_eq!(p.output_basis(0, &[]).unwrap(), Some(per_unit));
    }
}

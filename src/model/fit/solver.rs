//! The weighted non-negative least squares at fixed shape parameters: one column per spectral
//! kind (its σ²(τ) per unit squared amplitude), the weights and EDF iterated on the model, and the
//! assembly of fitted terms and points from the solution.
//!
//! The amplitudes enter σ²(τ) linearly as squares, so at fixed shapes (frequencies, time
//! constants) the fit is an NNLS; the shapes are searched around it (`searches`), an output column
//! (a quantizer) is settled around it (`quantizer`) and the uncertainties come from its Jacobian
//! (`covariance`). Each solve is an iteratively reweighted Gauss–Newton step on the robust log
//! cost of `scoring`, damped while the cost rises.
//!
//! # References
//! Lawson & Hanson, "Solving Least Squares Problems", 1974 (NNLS); Riley, NIST SP 1065 (2008),
//! Table 12 (EDF).

use super::quantizer::OutputState;
use super::scoring::{failing_tau, log_bias, log_cost, log_cost_of, log_ratios, rms, robust_edf_of, z_scores};
use super::types::{term_of, FitError, FitPoint};
use super::CurveFit;
use crate::allan::AllanPoint;
use crate::model::effects::{Effect, EffectKind};
use crate::allan::edf::edf_with_fourth_cumulant;
use crate::model::measure::{edf_oavar, edf_of_mix, NoiseClass};
use crate::model::nnls::nnls_from;
use nalgebra::{DMatrix, DVector};
use std::cell::Cell;

/// Fewest periods a line (a shape parameter in Hz without a range of its own) has in the record:
/// its frequency is searched from LINE_PERIODS/(3·τmax), τmax being at most a third of the record.
///
/// Why: searched from 1/(4·τmax) (0.75–0.95 periods), a sinusoid of 0.85 periods drew its curve
/// through a 24 σ ramp on a 90 min record and was named before it, its amplitude ± 100 %. Two
/// periods are the fewest in which a sine is not a trend: over one, its arc is a drift's shape.
const LINE_PERIODS: f64 = 2.0;

/// One spectral kind as the solver sees it.
pub(super) struct Column {
    pub(super) kind: &'static dyn EffectKind,
    /// Reference amplitude used to evaluate the unit basis.
    pub(super) amp_ref: f64,
    pub(super) class: NoiseClass,
    /// For each shape parameter: (index in schema, log-range lo, log-range hi).
    pub(super) shapes: Vec<(usize, f64, f64)>,
}

pub(super) struct Problem<'a> {
    pub(super) points: &'a [AllanPoint],
    pub(super) columns: Vec<Column>,
    /// Set by [`Problem::settle_output_columns`]: what the output columns are computed from
    /// (without it they use [`Effect::avar`]).
    pub(super) output: Option<OutputState>,
    /// Columns left out of the model (zero basis) while [`Problem::search_shapes`] has not yet
    /// searched their shapes.
    pub(super) muted: Vec<bool>,
    /// Peaks of the samples' periodogram, (frequency, bin width) in Hz: extra candidates of
    /// every frequency's scan (see [`Problem::search_shapes`]).
    pub(super) line_hints: Vec<(f64, f64)>,
    /// The fourth cumulant of the white rate noise (0: Gaussian), which widens every point's EDF
    /// ([`edf_with_fourth_cumulant`]).
    pub(super) fourth_cumulant: f64,
    /// Per point, the EDFs its model's parts are mixed from ([`edf_of_mix`]): made once, as
    /// the columns' classes are fixed.
    edfs: Vec<PointEdfs>,
    /// The columns with a positive amplitude in the latest NNLS: the next one's guess
    /// ([`nnls_from`]; the same answers, fewer solves), the searches' trials being neighbours.
    positive: Cell<Vec<bool>>,
}

/// The EDFs of one point's estimate under each noise class a model of the problem mixes
/// ([`edf_oavar`] at the point's length and factor).
///
/// Why kept: the fit mixes them at every point of every round ([`Problem::solve`]), and each is
/// a few divisions; made once per problem, `cargo bench --bench diagnose` ran 5 % faster.
struct PointEdfs {
    /// White FM's: the first round's EDF, and a mix's when it has no variance.
    white_fm: f64,
    /// Each column's class's, in column order.
    columns: Vec<f64>,
    /// The offset's class's (the output columns' while they are held).
    offset: f64,
}

/// A weighted NNLS solution at fixed shape parameters.
pub(super) struct Solution {
    /// Squared amplitudes c_j.
    pub(super) c: Vec<f64>,
    pub(super) model: Vec<f64>,
    pub(super) edf: Vec<f64>,
    pub(super) z: Vec<f64>,
    pub(super) chi2: f64,
    /// [`log_cost`] of `model` against `meas` at `edf` (the objective the searches minimise).
    pub(super) cost: f64,
    /// Per-column basis values (unit amplitude) at each point.
    pub(super) basis: Vec<Vec<f64>>,
}

impl<'a> Problem<'a> {
    pub(super) fn new(points: &'a [AllanPoint], kinds: &[&'static dyn EffectKind]) -> Result<Self, FitError> {
        let tau_min = points.first().map_or(1.0, |p| p.tau);
        let tau_max = points.last().map_or(1.0, |p| p.tau);
        let columns = kinds
            .iter()
            .map(|&kind| {
                let schema = kind.schema();
                let (lo, hi) = schema[0].bounds;
                let amp_ref = if lo <= 1.0 && 1.0 <= hi { 1.0 } else { hi.min(lo.abs().max(hi) * 0.5) };
                let shapes = schema
                    .iter()
                    .enumerate()
                    .skip(1)
                    .map(|(i, s)| {
                        // A time constant shorter than the shortest τ is a filter, not a wandering
                        // bias: that regime belongs to the kinds that say so (`search_range`).
                        // A frequency of fewer than two periods in the record (τmax is at most a
                        // third of it) is a drift: over less than a cycle a sine's arc is a trend,
                        // which a ramp, a random walk or temperature describes with its own evidence.
                        let (a, b) = kind.search_range(i, tau_min, tau_max).unwrap_or(match s.unit {
                            "Hz" => (LINE_PERIODS / (3.0 * tau_max), 1.0 / (2.0 * tau_min)),
                            _ => (tau_min, 4.0 * tau_max),
                        });
                        let a = a.max(s.bounds.0).max(f64::MIN_POSITIVE);
                        let b = b.min(s.bounds.1).max(a);
                        (i, a.ln(), b.ln())
                    })
                    .collect();
                Column {
                    kind,
                    amp_ref,
                    class: NoiseClass::WhiteFm,
                    shapes,
                }
            })
            .collect::<Vec<_>>();
        let mut problem = Problem {
            points,
            columns,
            output: None,
            muted: Vec::new(),
            line_hints: Vec::new(),
            fourth_cumulant: 0.0,
            positive: Cell::new(Vec::new()),
            edfs: Vec::new(),
        };
        for j in 0..problem.columns.len() {
            let shapes = problem.initial_shapes();
            let eff = problem.build(j, 1.0, &shapes)?;
            problem.columns[j].class = NoiseClass::from_slope(eff.explain().avar_slope);
        }
        let offset_class = problem.offset_class();
        problem.edfs = points
            .iter()
            .map(|p| {
                let edf = |class| edf_oavar(class, Self::n_phase(p), p.m);
                PointEdfs {
                    white_fm: edf(NoiseClass::WhiteFm),
                    columns: problem.columns.iter().map(|c| edf(c.class)).collect(),
                    offset: edf(offset_class),
                }
            })
            .collect();
        Ok(problem)
    }

    /// Middle of each shape range, flattened over columns, log scale.
    pub(super) fn initial_shapes(&self) -> Vec<f64> {
        self.columns
            .iter()
            .flat_map(|c| c.shapes.iter().map(|&(_, lo, hi)| 0.5 * (lo + hi)))
            .collect()
    }

    /// Builds column j's effect with amplitude `amp` and the shapes (log) of `shapes`.
    pub(super) fn build(&self, j: usize, amp: f64, shapes: &[f64]) -> Result<Box<dyn Effect>, FitError> {
        let col = &self.columns[j];
        let offset: usize = self.columns[..j].iter().map(|c| c.shapes.len()).sum();
        let mut values = vec![amp; col.kind.schema().len()];
        for (k, &(i, _, _)) in col.shapes.iter().enumerate() {
            values[i] = shapes[offset + k].exp();
        }
        Ok(col.kind.build(&values)?)
    }

    pub(super) fn basis(&self, shapes: &[f64]) -> Result<Vec<Vec<f64>>, FitError> {
        (0..self.columns.len())
            .map(|j| {
                if self.muted.get(j).copied().unwrap_or(false) {
                    return Ok(vec![0.0; self.points.len()]);
                }
                if let Some(col) = self.output_basis(j, shapes)? {
                    return Ok(col);
                }
                let a = self.columns[j].amp_ref;
                let eff = self.build(j, a, shapes)?;
                let slope = self.output.as_ref().and_then(|s| s.jacobian.get(j));
                Ok(self
                    .points
                    .iter()
                    .enumerate()
                    .map(|(i, p)| {
                        eff.avar(p.tau).unwrap_or(0.0).max(0.0) / (a * a)
                            + slope.map_or(0.0, |d| d[i])
                    })
                    .collect())
            })
            .collect()
    }

    fn n_phase(p: &AllanPoint) -> usize {
        p.terms + 2 * p.m
    }

    /// `edf`, the Gaussian EDF of point `p` under a model of value `avar` there, widened for the
    /// white noise's fourth cumulant ([`edf_with_fourth_cumulant`]; `edf` itself when Gaussian).
    fn widened(&self, edf: f64, avar: f64, p: &AllanPoint) -> f64 {
        edf_with_fourth_cumulant(edf, avar, p.m, p.terms, self.fourth_cumulant)
    }

    /// The noise class of the model's fixed part ([`Problem::offset`]): the first output
    /// column's, else white PM.
    fn offset_class(&self) -> NoiseClass {
        (0..self.columns.len())
            .find(|&j| self.is_output(j))
            .map_or(NoiseClass::WhitePm, |j| self.columns[j].class)
    }

    /// Weighted NNLS with the weights and EDF iterated on the model.
    pub(super) fn solve(&self, shapes: &[f64], iterations: usize) -> Result<Solution, FitError> {
        let basis = self.basis(shapes)?;
        let offset = self.offset(shapes)?;
        let k = self.points.len();
        let jn = self.columns.len();
        let meas: Vec<f64> = self.points.iter().map(|p| p.avar).collect();
        let mut edf: Vec<f64> =
            self.edfs.iter().zip(self.points).map(|(e, p)| self.widened(e.white_fm, p.avar, p)).collect();
        let mut model = meas.clone();
        let mut c = vec![0.0; jn];
        let mut best_cost = f64::INFINITY;
        let mut positive = self.positive.take();
        let mut ratios = log_ratios(&meas, &model);
        for _ in 0..iterations {
            // Iteratively reweighted Gauss–Newton on [`log_cost`], linearised around the current
            // model: target tᵢ = modelᵢ·(1 + ln(measᵢ/modelᵢ)), weight 1/(modelᵢ·√(2/wᵢ)) with
            // wᵢ = edfᵢ/(1 + zᵢ²/C²) ([`robust_edf_of`]); `ratios` are the current model's.
            let wedf = robust_edf_of(&ratios, &meas, &model, &edf);
            let sd: Vec<f64> = (0..k)
                .map(|i| {
                    let base = if model[i] > 0.0 { model[i] } else { meas[i] };
                    base * (2.0 / wedf[i]).sqrt()
                })
                .collect();
            let target: Vec<f64> = (0..k)
                .map(|i| {
                    if model[i] > 0.0 {
                        model[i] * (1.0 + ratios[i] - log_bias(edf[i]))
                    } else {
                        meas[i]
                    }
                })
                .collect();
            let a = DMatrix::from_fn(k, jn, |i, j| basis[j][i] / sd[i]);
            let b = DVector::from_fn(k, |i, _| (target[i] - offset[i]) / sd[i]);
            let x = nnls_from(&a, &b, &mut positive)?;
            let mut trial: Vec<f64> = x.iter().copied().collect();
            // Damping: halve the step toward the new solution while the log cost rises (from the
            // second round: the first has no cost to rise from).
            let halvings = if best_cost.is_infinite() { 0 } else { 8 };
            for _ in 0..halvings {
                let m: Vec<f64> = (0..k)
                    .map(|i| offset[i] + (0..jn).map(|j| trial[j] * basis[j][i]).sum::<f64>())
                    .collect();
                let cost = log_cost(&meas, &m, &edf);
                if cost <= best_cost || best_cost.is_infinite() {
                    break;
                }
                trial = trial.iter().zip(&c).map(|(t, o)| 0.5 * (t + o)).collect();
            }
            c = trial;
            for (i, e) in self.edfs.iter().enumerate() {
                // The parts (variance, its class's EDF) of the model at point i.
                let parts = || {
                    (0..jn)
                        .map(|j| (c[j] * basis[j][i], e.columns[j]))
                        .chain((offset[i] > 0.0).then_some((offset[i], e.offset)))
                };
                model[i] = parts().map(|p| p.0).sum();
                edf[i] = self.widened(edf_of_mix(model[i], parts(), || e.white_fm), model[i], &self.points[i]);
            }
            ratios = log_ratios(&meas, &model);
            best_cost = log_cost_of(&ratios, &model, &edf);
        }
        self.positive.set(positive);
        let cost = if iterations == 0 { log_cost_of(&ratios, &model, &edf) } else { best_cost };
        let z = z_scores(&meas, &model, &edf);
        let chi2 = z.iter().map(|v| v * v).sum();
        Ok(Solution { c, model, edf, z, chi2, cost, basis })
    }

    /// Builds terms, points and uncertainties from a solution.
    pub(super) fn assemble(
        &self,
        kinds: &[&'static dyn EffectKind],
        shapes: &[f64],
        sol: &Solution,
        n_params: usize,
    ) -> Result<CurveFit, FitError> {
        let cov = self.covariance(shapes, sol);
        let mut terms = Vec::with_capacity(kinds.len());
        let mut offset = 0;
        for (j, col) in self.columns.iter().enumerate() {
            let amp = sol.c[j].max(0.0).sqrt();
            let eff = self.build(j, amp, shapes)?;
            let mut sigmas = vec![None; col.kind.schema().len()];
            if let Some(var_c) = cov.as_ref().and_then(|c| c.get(j).copied().flatten()) {
                sigmas[0] = Some(if amp > 0.0 {
                    var_c.sqrt() / (2.0 * amp)
                } else {
                    var_c.sqrt().sqrt()
                });
            }
            for (k, &(i, _, _)) in col.shapes.iter().enumerate() {
                let idx = self.columns.len() + offset + k;
                if let Some(v) = cov.as_ref().and_then(|c| c.get(idx).copied().flatten()) {
                    sigmas[i] = Some(shapes[offset + k].exp() * v.sqrt());
                }
            }
            offset += col.shapes.len();
            let curve = sol.basis[j].iter().map(|b| b * sol.c[j]).collect();
            terms.push(term_of(&*eff, &sigmas, curve));
        }
        let points: Vec<FitPoint> = self
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| FitPoint {
                m: p.m,
                tau: p.tau,
                measured: p.avar,
                model: sol.model[i],
                edf: sol.edf[i],
                z: sol.z[i],
                bridged: false,
            })
            .collect();
        let taus: Vec<f64> = points.iter().map(|p| p.tau).collect();
        Ok(CurveFit {
            failing_tau: failing_tau(&taus, &sol.z),
            fit_error: rms(&sol.z),
            chi2: sol.chi2,
            terms,
            points,
            n_params,
            classes: self.columns.iter().map(|c| c.class).collect(),
            fourth_cumulant: self.fourth_cumulant,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::{find, id};
    use crate::model::fit::exact_points;

    #[test]
    fn columns_take_the_noise_class_of_their_slope() {
        let points = exact_points(|tau| 1e-6 / tau, 1_000_000);
        let kinds: Vec<_> = [id::QUANTIZATION, id::WHITE, id::BIAS_INSTABILITY, id::RANDOM_WALK, id::GAUSS_MARKOV]
            .iter()
            .map(|&i| find(i).unwrap())
            .collect();
        let problem = Problem::new(&points, &kinds).unwrap();
        let classes: Vec<NoiseClass> = problem.columns.iter().map(|c| c.class).collect();
        assert_eq!(
            classes,
            [
                NoiseClass::WhitePm,
                NoiseClass::WhiteFm,
                NoiseClass::FlickerFm,
                NoiseClass::RandomWalkFm,
                NoiseClass::WhiteFm, // no slope: the most generous EDF
            ]
        );
        // One shape (the Gauss–Markov time constant), started in the middle of its log range
        // [2·τmin, 4·τmax] = [0.02 s, 163.84 s] (`gauss_markov`'s own: shorter is a filter).
        let mid = 0.5 * (0.02f64.ln() + (4.0 * 40.96f64).ln());
        assert_eq!(problem.initial_shapes(), [mid]);
    }

    #[test]
    fn the_basis_is_each_column_per_unit_squared_amplitude() {
        let points = exact_points(|tau| 1e-6 / tau, 1_000_000);
        let kinds = [find(id::WHITE).unwrap(), find(id::RANDOM_WALK).unwrap()];
        let problem = Problem::new(&points, &kinds).unwrap();
        let basis = problem.basis(&[]).unwrap();
        for (i, p) in points.iter().enumerate() {
            assert_eq!(basis[0][i], 1.0 / p.tau); // n²/τ at n = 1
            assert_eq!(basis[1][i], p.tau / 3.0); // k²·τ/3 at k = 1
        }
    }

    #[test]
    fn solve_recovers_squared_amplitudes_of_an_exact_curve() {
        let (n2, k2) = (1e-6, 1e-6); // crossing at τ = √3 s, inside the grid
        let points = exact_points(|tau| n2 / tau + k2 * tau / 3.0, 1_000_000);
        let kinds = [find(id::WHITE).unwrap(), find(id::RANDOM_WALK).unwrap()];
        let sol = Problem::new(&points, &kinds).unwrap().solve(&[], 6).unwrap();
        // The log fit matches the χ²-biased log of the estimates (`log_bias`): within ~1/EDF.
        let edf_min = sol.edf.iter().copied().fold(f64::INFINITY, f64::min);
        assert!((sol.c[0] / n2 - 1.0).abs() < 2.0 / edf_min, "{} vs {n2}", sol.c[0]);
        assert!((sol.c[1] / k2 - 1.0).abs() < 2.0 / edf_min, "{} vs {k2}", sol.c[1]);
        // The model is the basis weighted by the solution.
        for i in 0..points.len() {
            let model = sol.c[0] * sol.basis[0][i] + sol.c[1] * sol.basis[1][i];
            assert!((sol.model[i] / model - 1.0).abs() < 1e-12);
        }
        // z is the contract's, and the cost the searches minimise is the log cost of the model.
        let meas: Vec<f64> = points.iter().map(|p| p.avar).collect();
        assert_eq!(sol.z, z_scores(&meas, &sol.model, &sol.edf));
        assert_eq!(sol.cost.to_bits(), log_cost(&meas, &sol.model, &sol.edf).to_bits());
        // Without rounds the model is the measurement itself, and so is the cost.
        let none = Problem::new(&points, &kinds).unwrap().solve(&[], 0).unwrap();
        assert_eq!(none.cost.to_bits(), log_cost(&meas, &meas, &none.edf).to_bits());
    }
}

//! Scoring a model against the measurement: the contract's z and `fit_error`, the failing τ
//! intervals, and the robust log cost the solver minimises.
//!
//! Two scores on purpose. The contract's z (docs/design.md §5) scales the residual by the model's
//! own standard deviation, σ²_model·√(2/EDF): it is what a user reads and what `--strict` tests.
//! The solver instead minimises a Cauchy loss of the log residual ([`log_cost`]): in log σ² over-
//! and under-prediction weigh alike, and a few points the model cannot follow (a vibration line,
//! the huge EDF of the shortest τ) stop dictating the fit. Minimising Σ z² directly was rejected:
//! it forgives a model that over-predicts where the EDF is small.

/// |z| above which a τ is "failing" (docs/design.md §5, **contract**).
pub const FAILING_Z: f64 = 3.0;

/// **contract**: RMS over the τ grid of z = (σ²_meas − σ²_model)/(σ²_model·√(2/EDF)).
///
/// # Formula
/// ```text
/// zᵢ = (measᵢ − modelᵢ) / (modelᵢ·√(2/edfᵢ)),   fit_error = √(Σ zᵢ² / K)
/// ```
/// where K is the number of τ points. About 1 when the model explains the measurement.
///
/// ```
/// use fdavar::model::fit::fit_error;
/// assert_eq!(fit_error(&[1.0, 1.0], &[1.0, 1.0], &[50.0, 50.0]), 0.0);
/// assert!((fit_error(&[1.2], &[1.0], &[50.0]) - 1.0).abs() < 1e-12);
/// ```
pub fn fit_error(measured: &[f64], model: &[f64], edf: &[f64]) -> f64 {
    let z = z_scores(measured, model, edf);
    rms(&z)
}

/// z scores of the contract (see [`fit_error`]); a non-positive model gives z = ±∞ or 0.
pub fn z_scores(measured: &[f64], model: &[f64], edf: &[f64]) -> Vec<f64> {
    measured
        .iter()
        .zip(model)
        .zip(edf)
        .map(|((&me, &mo), &e)| {
            let d = me - mo;
            let sd = mo * (2.0 / e).sqrt();
            if sd > 0.0 {
                d / sd
            } else if d == 0.0 {
                0.0
            } else {
                f64::INFINITY.copysign(d)
            }
        })
        .collect()
}

pub(super) fn rms(z: &[f64]) -> f64 {
    if z.is_empty() {
        return 0.0;
    }
    (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt()
}

/// **contract**: the maximal τ intervals [lo, hi] (seconds) where |z| > 3.
///
/// ```
/// use fdavar::model::fit::failing_tau;
/// let tau = [1.0, 2.0, 4.0, 8.0, 16.0];
/// assert_eq!(failing_tau(&tau, &[0.0, 4.0, -5.0, 1.0, 3.5]), vec![[2.0, 4.0], [16.0, 16.0]]);
/// ```
pub fn failing_tau(tau: &[f64], z: &[f64]) -> Vec<[f64; 2]> {
    let mut out: Vec<[f64; 2]> = Vec::new();
    let mut open: Option<[f64; 2]> = None;
    for (&t, &zi) in tau.iter().zip(z) {
        if zi.abs() > FAILING_Z {
            open = Some(match open {
                Some([lo, _]) => [lo, t],
                None => [t, t],
            });
        } else if let Some(span) = open.take() {
            out.push(span);
        }
    }
    out.extend(open);
    out
}

/// Scale C of the robust loss, in units of z: points beyond |z| ≈ C lose their pull on the fit.
///
/// Why robust: with diagonal weights EDF/2 a few τ points of very large EDF (the shortest τ of a long
/// record) or a bump the model cannot follow (a vibration line) pulled a wrong model off *every*
/// point — on the ADIS16405's accel axes N,B,K lay above all points from 1.5 to 20 s. With the
/// Cauchy loss the points the model cannot explain stop dictating it, and it follows the others,
/// failing (large |z|) only where it fails. C = 3 is the contract's failing |z|; for a model that
/// explains the data (|z| ~ N(0,1)) the weights are 0.9 ± 0.1 and the estimates move little.
const ROBUST_C: f64 = 3.0;

/// zᵢ of the log fit: √(edfᵢ/2)·(ln(measᵢ/modelᵢ) − bias(edfᵢ)), the standardised log residual.
fn log_z(y: f64, m: f64, e: f64) -> f64 {
    log_z_of((y / m).ln(), e)
}

/// [`log_z`] from ln(measᵢ/modelᵢ) ([`log_ratios`]).
fn log_z_of(log_ratio: f64, e: f64) -> f64 {
    (0.5 * e).sqrt() * (log_ratio - log_bias(e))
}

/// ln(measᵢ/modelᵢ) of every point (meaningless where the model is not positive, and unread
/// there): what [`log_cost_of`], [`robust_edf_of`] and the fit's linearisation share.
///
/// Why once: the fit's every round read it three times (its weights, its target, its cost), a
/// logarithm per point each, and the searches a fourth; logarithms were 2.3 % of `fdavar
/// analyze`'s CPU.
pub(super) fn log_ratios(meas: &[f64], model: &[f64]) -> Vec<f64> {
    meas.iter().zip(model).map(|(&y, &m)| (y / m).ln()).collect()
}

/// The fit's objective: Σ C²·ln(1 + zᵢ²/C²) over the log residuals zᵢ ([`log_z`]) — the Cauchy
/// (Lorentzian) loss of the log-normal approximation of the χ² likelihood of AVAR estimates
/// (Σ zᵢ² for small z). In log σ² it weighs over- and under-prediction alike, where the contract's
/// z (scaled by the model) forgives a model that over-predicts where the EDF is small.
///
/// # References
/// P. J. Huber, E. M. Ronchetti, "Robust Statistics", 2nd ed., Wiley 2009, §7 (M-estimators,
/// iteratively reweighted least squares).
pub(super) fn log_cost(meas: &[f64], model: &[f64], edf: &[f64]) -> f64 {
    meas.iter().zip(model).zip(edf).map(|((&y, &m), &e)| point_cost(m, || log_z(y, m, e))).sum()
}

/// [`log_cost`] from the points' [`log_ratios`], the same number.
pub(super) fn log_cost_of(log_ratios: &[f64], model: &[f64], edf: &[f64]) -> f64 {
    log_ratios.iter().zip(model).zip(edf).map(|((&r, &m), &e)| point_cost(m, || log_z_of(r, e))).sum()
}

/// One point's term of [`log_cost`], its log residual `z` computed only where the model is
/// positive.
fn point_cost(m: f64, z: impl FnOnce() -> f64) -> f64 {
    if m > 0.0 {
        ROBUST_C * ROBUST_C * (z() / ROBUST_C).powi(2).ln_1p()
    } else {
        f64::MAX / 1e3
    }
}

/// The IRLS weights of [`log_cost`] as effective EDFs: edfᵢ/(1 + zᵢ²/C²) at the current model, from
/// its [`log_ratios`].
pub(super) fn robust_edf_of(log_ratios: &[f64], meas: &[f64], model: &[f64], edf: &[f64]) -> Vec<f64> {
    log_ratios
        .iter()
        .zip(meas)
        .zip(model)
        .zip(edf)
        .map(|(((&r, &y), &m), &e)| {
            let z = if m > 0.0 && y > 0.0 { log_z_of(r, e) } else { 0.0 };
            e / (1.0 + (z / ROBUST_C).powi(2))
        })
        .collect()
}

/// E[ln(σ̂²/σ²)] for an estimate with `edf` degrees of freedom: the log of a χ²_ν/ν variable is
/// biased low, by ψ(ν/2) − ln(ν/2) ≈ −1/ν − 1/(3ν²); without this a log fit would pull the model
/// down where the EDF is small (long τ).
pub(super) fn log_bias(edf: f64) -> f64 {
    let nu = edf.max(1.0);
    -1.0 / nu - 1.0 / (3.0 * nu * nu)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn z_is_the_residual_in_standard_deviations_of_the_model() {
        // sd = model·√(2/edf): 1·√(2/8) = 0.5, 2·√(2/2) = 2, 2·√(2/32) = 0.5 (all exact in f64).
        let z = z_scores(&[1.5, 0.0, 5.0], &[1.0, 2.0, 2.0], &[8.0, 2.0, 32.0]);
        assert_eq!(z, [1.0, -1.0, 6.0]);
        // fit_error = √((1 + 1 + 36)/3).
        assert_eq!(fit_error(&[1.5, 0.0, 5.0], &[1.0, 2.0, 2.0], &[8.0, 2.0, 32.0]), (38.0f64 / 3.0).sqrt());
    }

    #[test]
    fn a_non_positive_model_gives_infinite_or_zero_z() {
        let z = z_scores(&[1.0, -1.0, 0.0], &[0.0, 0.0, 0.0], &[8.0, 8.0, 8.0]);
        assert_eq!(z, [f64::INFINITY, f64::NEG_INFINITY, 0.0]);
        assert_eq!(rms(&[]), 0.0);
    }

    #[test]
    fn failing_tau_groups_neighbouring_points_beyond_three() {
        let tau = [1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0];
        // |z| = 3 exactly does not fail; a sign change inside a run does not split it.
        let z = [3.0, 3.5, -4.0, 0.0, 5.0, -3.01, 1.0];
        assert_eq!(failing_tau(&tau, &z), vec![[2.0, 4.0], [16.0, 32.0]]);
        // A run open at the last point is closed there.
        assert_eq!(failing_tau(&tau[..2], &[0.0, 9.0]), vec![[2.0, 2.0]]);
        assert!(failing_tau(&tau, &[0.0; 7]).is_empty());
    }

    #[test]
    fn log_bias_is_the_second_order_digamma_expansion() {
        assert_eq!(log_bias(10.0), -0.1 - 1.0 / 300.0);
        // Fewer than one degree of freedom is read as one.
        assert_eq!(log_bias(0.5), -1.0 - 1.0 / 3.0);
    }

    #[test]
    fn log_cost_and_robust_edf_at_a_residual_of_c() {
        // edf = 8: z = √4·(ln(y/m) − bias) = 3 = C when ln(y/m) = 1.5 + bias.
        let (m, e) = (2.0, 8.0);
        let y = m * (1.5 + log_bias(e)).exp();
        let rounding = 1e-12; // of exp and ln at this size
        assert!((log_z(y, m, e) - ROBUST_C).abs() < rounding);
        // Cauchy loss C²·ln(1 + z²/C²) = 9·ln 2 there, and the IRLS weight halves the EDF.
        assert!((log_cost(&[y], &[m], &[e]) - 9.0 * 2f64.ln()).abs() < 9.0 * rounding);
        let r = log_ratios(&[y], &[m]);
        assert!((robust_edf_of(&r, &[y], &[m], &[e])[0] - 4.0).abs() < 4.0 * rounding);
        assert_eq!(log_cost_of(&r, &[m], &[e]).to_bits(), log_cost(&[y], &[m], &[e]).to_bits());
        // A non-positive model costs a fixed large amount and keeps its EDF.
        assert_eq!(log_cost(&[y], &[0.0], &[e]), f64::MAX / 1e3);
        assert_eq!(robust_edf_of(&log_ratios(&[y], &[0.0]), &[y], &[0.0], &[e]), [e]);
    }
}

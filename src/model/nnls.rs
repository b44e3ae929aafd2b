//! Non-negative least squares (Lawson–Hanson active set) on nalgebra.
//!
//! The Allan signatures of the noise terms are linear in the squared coefficients (N², B², K², …),
//! and a squared coefficient cannot be negative. Plain least squares happily returns a negative N²
//! when two terms compete; clipping afterwards is not a least-squares solution. Lawson–Hanson is
//! exact, finite, and small enough to own (a projected-gradient solver was rejected: its
//! convergence on columns spanning 10+ decades is slow without the active-set structure).
//!
//! # References
//! Lawson C. L., Hanson R. J., "Solving Least Squares Problems", Prentice-Hall, 1974, ch. 23.

use nalgebra::{DMatrix, DVector};

/// Why the NNLS solver could not return a solution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NnlsError {
    /// `a` has a different number of rows than `b` has entries.
    #[error("matrix has {rows} rows but the right-hand side has {len} entries")]
    Shape {
        /// Rows of `a`.
        rows: usize,
        /// Entries of `b`.
        len: usize,
    },
    /// An entry of `a` or `b` is NaN or infinite.
    #[error("the least-squares system contains a non-finite value")]
    NotFinite,
}

/// Solves min ‖A·x − b‖₂ subject to x ≥ 0.
///
/// Columns are scaled to unit norm internally, so columns that differ by many orders of magnitude
/// (τ⁻² next to τ²) are handled; an all-zero column gets x = 0.
///
/// # Formula
/// ```text
/// x* = argmin_{x ≥ 0} Σ_i (Σ_j A_ij·x_j − b_i)²
/// ```
///
/// # Errors
/// [`NnlsError`] on a shape mismatch or a non-finite entry.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// let a = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
/// let b = DVector::from_vec(vec![2.0, -1.0, 1.0]);
/// let x = fdavar::model::nnls::nnls(&a, &b).unwrap();
/// assert!((x[0] - 1.5).abs() < 1e-12 && x[1] == 0.0);
/// ```
pub fn nnls(a: &DMatrix<f64>, b: &DVector<f64>) -> Result<DVector<f64>, NnlsError> {
    nnls_from(a, b, &mut Vec::new())
}

/// [`nnls`] started from a guess of which variables are positive at the optimum, e.g. the answer
/// to a neighbouring problem: `passive` holds the guess (empty: none) and receives this answer's.
///
/// The answer is the one [`nnls`] gives whenever the optimum's positive set is unique (the
/// columns independent, no gradient within the tolerance of entering). The active-set iteration
/// ends with the least-squares solution on the positive variables, no more; a guess is taken only
/// when that solution is positive and no other variable's gradient would enter, which is where the
/// iteration from nothing stops, so the final solve is the same computation. Otherwise the
/// iteration runs from nothing. Checked bit for bit on random problems (the tests) and on every
/// fit of the recordings the suite diagnoses (their JSON unchanged).
///
/// Why: the fit solves a sequence of problems that differ a little (its reweighting rounds,
/// the points of a scan), and from nothing each costs one solve per variable added, the largest
/// last; a right guess costs that last one alone.
///
/// # Errors
/// As [`nnls`].
pub fn nnls_from(a: &DMatrix<f64>, b: &DVector<f64>, passive: &mut Vec<bool>) -> Result<DVector<f64>, NnlsError> {
    let (rows, cols) = a.shape();
    if rows != b.len() {
        return Err(NnlsError::Shape { rows, len: b.len() });
    }
    if a.iter().chain(b.iter()).any(|v| !v.is_finite()) {
        return Err(NnlsError::NotFinite);
    }
    let norms: Vec<f64> = (0..cols).map(|j| a.column(j).norm()).collect();
    let mut s = a.clone();
    for (j, &n) in norms.iter().enumerate() {
        if n > 0.0 {
            s.column_mut(j).scale_mut(1.0 / n);
        }
    }
    let usable: Vec<bool> = norms.iter().map(|&n| n > 0.0).collect();
    let tol = 1e-12 * (1.0 + b.norm()) * (cols.max(1) as f64);
    let z = if rows > cols {
        // With S = QR (Q: k×p, orthonormal columns), ‖S·x − b‖² = ‖R·x − Qᵀb‖² + ‖b − QQᵀb‖²
        // for every x, and Sᵀ(b − S·x) = Rᵀ(Qᵀb − R·x): the same problem, the same iterates, on
        // the p×p triangle. Why: the active set solves one least-squares problem per passive
        // set, and their SVDs of k×p columns (k ≈ 40 τ, p ≤ 7) were the fit's largest cost.
        let qr = s.qr();
        let mut qtb = b.clone();
        qr.q_tr_mul(&mut qtb);
        lawson_hanson(&qr.unpack_r(), &qtb.rows(0, cols).into_owned(), &usable, tol, passive)
    } else {
        lawson_hanson(&s, b, &usable, tol, passive)
    };
    Ok(DVector::from_iterator(
        cols,
        (0..cols).map(|j| if usable[j] { z[j] / norms[j] } else { 0.0 }),
    ))
}

/// The active-set iteration on a column-scaled matrix, unless `passive` (see [`nnls_from`]) is
/// its answer; `passive` receives the answer's positive variables.
/// `tol`: the gradient a column must exceed to enter, and the value under which it leaves.
fn lawson_hanson(a: &DMatrix<f64>, b: &DVector<f64>, usable: &[bool], tol: f64, passive: &mut Vec<bool>) -> DVector<f64> {
    let cols = a.ncols();
    if passive.len() == cols && passive.iter().any(|&p| p) {
        let s = solve_passive(a, b, passive);
        let positive = (0..cols).filter(|&j| passive[j]).all(|j| usable[j] && s[j] > 0.0);
        if positive {
            let w = a.tr_mul(&(b - a * &s));
            if !(0..cols).any(|j| usable[j] && !passive[j] && w[j] > tol) {
                return s;
            }
        }
    }
    passive.clear();
    passive.resize(cols, false);
    let mut x = DVector::zeros(cols);
    let max_outer = 3 * cols + 10;
    for _ in 0..max_outer {
        let w = a.tr_mul(&(b - a * &x));
        let candidate = (0..cols)
            .filter(|&j| usable[j] && !passive[j] && w[j] > tol)
            .max_by(|&i, &j| w[i].total_cmp(&w[j]));
        let Some(t) = candidate else { break };
        passive[t] = true;
        let mut added_once = false;
        for _ in 0..max_outer {
            let s = solve_passive(a, b, passive);
            let all_positive = (0..cols).filter(|&j| passive[j]).all(|j| s[j] > 0.0);
            if all_positive {
                x = s;
                added_once = true;
                break;
            }
            // Step from x toward s until the first passive variable hits zero.
            let alpha = (0..cols)
                .filter(|&j| passive[j] && s[j] <= 0.0)
                .map(|j| x[j] / (x[j] - s[j]))
                .fold(f64::INFINITY, f64::min);
            let alpha = if alpha.is_finite() { alpha } else { 0.0 };
            x = &x + (s - &x) * alpha;
            for j in 0..cols {
                if passive[j] && x[j] <= tol {
                    passive[j] = false;
                    x[j] = 0.0;
                }
            }
        }
        if !added_once {
            break;
        }
    }
    x
}

/// Unconstrained least squares on the passive columns (others fixed at zero), by SVD.
fn solve_passive(a: &DMatrix<f64>, b: &DVector<f64>, passive: &[bool]) -> DVector<f64> {
    let idx: Vec<usize> = (0..a.ncols()).filter(|&j| passive[j]).collect();
    let sub = a.select_columns(&idx);
    let svd = sub.svd(true, true);
    let sol = svd
        .solve(b, 1e-13)
        .unwrap_or_else(|_| DVector::zeros(idx.len()));
    let mut out = DVector::zeros(a.ncols());
    for (k, &j) in idx.iter().enumerate() {
        out[j] = sol[k];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The KKT conditions characterise the NNLS optimum: x ≥ 0, w = Aᵀ(b − Ax) ≤ 0 where x = 0,
    /// and w = 0 where x > 0.
    fn assert_kkt(a: &DMatrix<f64>, b: &DVector<f64>, x: &DVector<f64>) {
        let w = a.transpose() * (b - a * x);
        let scale = a.norm() * b.norm();
        for j in 0..x.len() {
            assert!(x[j] >= 0.0);
            if x[j] > 0.0 {
                assert!(w[j].abs() <= 1e-9 * scale, "w[{j}] = {} at x = {}", w[j], x[j]);
            } else {
                assert!(w[j] <= 1e-9 * scale, "w[{j}] = {} > 0 at a bound", w[j]);
            }
        }
    }

    /// A problem of `rows` × `cols` (each drawn from its range), entries uniform in [−1, 1).
    fn random_problem(
        rng: &mut ChaCha8Rng,
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let rows = rng.random_range(rows);
        let cols = rng.random_range(cols);
        let a = DMatrix::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0));
        let b = DVector::from_fn(rows, |_, _| rng.random_range(-1.0..1.0));
        (a, b)
    }

    #[test]
    fn random_problems_satisfy_kkt() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..200 {
            let (a, b) = random_problem(&mut rng, 3..12, 1..6);
            let x = nnls(&a, &b).unwrap();
            assert_kkt(&a, &b, &x);
        }
    }

    #[test]
    fn a_guess_gives_the_answer_from_nothing_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (mut taken, mut wrong) = (0, 0);
        for _ in 0..300 {
            let (a, b) = random_problem(&mut rng, 6..40, 1..6);
            let cols = a.ncols();
            let want = nnls(&a, &b).unwrap();
            let right: Vec<bool> = want.iter().map(|&x| x > 0.0).collect();
            // The answer's own set, a random set, every column, and none.
            let random: Vec<bool> = (0..cols).map(|_| rng.random_bool(0.5)).collect();
            for guess in [right.clone(), random, vec![true; cols], Vec::new()] {
                let mut passive = guess.clone();
                let got = nnls_from(&a, &b, &mut passive).unwrap();
                let bits = |v: &DVector<f64>| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got), bits(&want), "guess {guess:?}");
                assert_eq!(passive, right, "the answer's positive variables come back");
                if guess == right && right.iter().any(|&p| p) {
                    taken += 1;
                } else if guess != right {
                    wrong += 1;
                }
            }
        }
        assert!(taken > 100 && wrong > 100, "{taken} right guesses, {wrong} wrong ones");
    }

    #[test]
    fn recovers_exact_nonnegative_solution_across_scales() {
        // Columns spanning 16 decades, as τ⁻², τ⁻¹, 1, τ, τ² do on a long record.
        let taus: Vec<f64> = (0..40).map(|k| 10f64.powf(-2.0 + k as f64 * 0.15)).collect();
        let a = DMatrix::from_fn(taus.len(), 5, |i, j| taus[i].powi(j as i32 - 2));
        let truth = DVector::from_vec(vec![1e-8, 3e-5, 0.0, 2e-7, 1e-11]);
        let b = &a * &truth;
        let x = nnls(&a, &b).unwrap();
        for j in 0..5 {
            assert!((x[j] - truth[j]).abs() <= 1e-6 * truth[j].max(1e-14), "{j}: {} vs {}", x[j], truth[j]);
        }
    }

    #[test]
    fn rejects_bad_input() {
        let a = DMatrix::from_element(2, 1, 1.0);
        assert_eq!(
            nnls(&a, &DVector::from_element(3, 1.0)),
            Err(NnlsError::Shape { rows: 2, len: 3 })
        );
        assert_eq!(
            nnls(&a, &DVector::from_vec(vec![1.0, f64::NAN])),
            Err(NnlsError::NotFinite)
        );
        let zero = DMatrix::zeros(2, 1);
        assert_eq!(nnls(&zero, &DVector::from_element(2, 1.0)).unwrap()[0], 0.0);
    }
}

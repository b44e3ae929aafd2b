//! The searches over shape parameters (a frequency, a time constant): a log grid scan of each
//! (a frequency's also at the peaks of the record's periodogram,
//! [`super::periodogram::line_candidates`]), refined by
//! golden section, around the NNLS of the amplitudes.
//!
//! The cost need not have one minimum in a shape parameter (two lines, a line beside a bump), so a
//! local minimiser started from the middle of the range could stop in the wrong one: the whole
//! range is scanned first (40 points a decade) and golden section refines the best cell. The
//! columns are searched one shape at a time, stagewise in the first round (see
//! [`Problem::search_shapes`] for why).

use super::solver::Problem;
use super::types::FitError;

impl Problem<'_> {
    /// Coordinate search over the shape parameters: a log grid scan, then golden-section refinement.
    ///
    /// The first round is stagewise: a column whose shapes have not been searched yet is left out
    /// of the model (muted) while the columns before it are searched, then every column takes part.
    /// Why: an unsearched column sits at the middle of its range, and there it may hold a feature
    /// that another column would otherwise take — a second line (`vibration`) starting at 0.18 Hz
    /// took a 0.2 Hz line before the `sinusoid` was searched, which then went to the other line:
    /// the suggestion read "add vibration at 0.2 Hz" beside a model whose sinusoid was at 0.2 Hz.
    pub(super) fn search_shapes(&mut self, mut shapes: Vec<f64>, iters: usize) -> Result<Vec<f64>, FitError> {
        let ranges: Vec<(f64, f64)> = self
            .columns
            .iter()
            .flat_map(|c| c.shapes.iter().map(|&(_, lo, hi)| (lo, hi)))
            .collect();
        // Which dimensions are a line's frequency (candidates from the periodogram).
        let frequency: Vec<bool> = self
            .columns
            .iter()
            .flat_map(|c| c.shapes.iter().map(|&(i, ..)| c.kind.schema()[i].name == super::FREQUENCY_PARAM))
            .collect();
        // The first shape dimension of each column, or None for a column without shapes.
        let mut first_dim = Vec::with_capacity(self.columns.len());
        let mut next = 0;
        for c in &self.columns {
            first_dim.push((!c.shapes.is_empty()).then_some(next));
            next += c.shapes.len();
        }
        let rounds = if shapes.len() > 1 { 2 } else { 1 };
        for round in 0..rounds {
            for (d, &(lo, hi)) in ranges.iter().enumerate() {
                self.muted = first_dim.iter().map(|f| round == 0 && f.is_some_and(|f| f > d)).collect();
                let cost = |s: &[f64]| -> Result<f64, FitError> {
                    let cost = self.solve(s, iters)?.cost;
                    Ok(if cost.is_finite() { cost } else { f64::MAX })
                };
                // 40 points per decade: neighbouring candidates differ by 6 %.
                let steps = (((hi - lo) / std::f64::consts::LN_10) * 40.0).ceil().max(8.0) as usize;
                let h = (hi - lo) / steps as f64;
                let mut best = (f64::MAX, shapes[d]);
                for s in 0..=steps {
                    let mut trial = shapes.clone();
                    trial[d] = lo + h * s as f64;
                    let c = cost(&trial)?;
                    if c < best.0 {
                        best = (c, trial[d]);
                    }
                }
                let eval = |v: f64, base: &Vec<f64>| -> Result<f64, FitError> {
                    let mut t = base.clone();
                    t[d] = v;
                    cost(&t)
                };
                // The periodogram's peaks too: a strong line's basin is narrower than the grid's
                // step (its nulls at τ = k/f deepen as it grows), and the scan stepped over it
                // onto the harmonic. A peak that does better is refined within its bin.
                let mut half = h;
                if frequency[d] {
                    for &(f, bin) in &self.line_hints {
                        let v = f.ln();
                        if (lo..=hi).contains(&v) {
                            let c = eval(v, &shapes)?;
                            if c < best.0 {
                                best = (c, v);
                                half = (bin / f).min(h);
                            }
                        }
                    }
                }
                let mid = golden_section((best.1 - half).max(lo), (best.1 + half).min(hi), 30, |v| eval(v, &shapes))?;
                shapes[d] = if eval(mid, &shapes)? <= best.0 { mid } else { best.1 };
            }
        }
        self.muted.clear();
        Ok(shapes)
    }
}

/// Golden-section search for the minimum of a unimodal `f` on [a, b]: `iterations` shrinkings of
/// the bracket by 0.618, each with one new evaluation. Returns the final bracket's midpoint.
pub(super) fn golden_section(
    mut a: f64,
    mut b: f64,
    iterations: usize,
    mut f: impl FnMut(f64) -> Result<f64, FitError>,
) -> Result<f64, FitError> {
    const G: f64 = 0.618_033_988_749_895;
    let mut x1 = b - G * (b - a);
    let mut x2 = a + G * (b - a);
    let (mut f1, mut f2) = (f(x1)?, f(x2)?);
    for _ in 0..iterations {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - G * (b - a);
            f1 = f(x1)?;
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + G * (b - a);
            f2 = f(x2)?;
        }
    }
    Ok(0.5 * (a + b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::{find, id, Effect, GaussMarkov};
    use crate::model::fit::exact_points;

    #[test]
    fn golden_section_finds_the_vertex_of_a_parabola() {
        let (a, b, iterations) = (0.0, 3.0, 60);
        let x = golden_section(a, b, iterations, |x| Ok((x - 1.3f64).powi(2))).unwrap();
        // The vertex stays inside the bracket, which shrinks by 0.618 per iteration.
        let half_width = 0.5 * (b - a) * 0.618_034f64.powi(iterations as i32);
        assert!((x - 1.3).abs() <= half_width, "{x}");
    }

    #[test]
    fn search_shapes_recovers_a_gauss_markov_time_constant() {
        let truth = GaussMarkov::new(1e-3, 0.5).unwrap();
        let points = exact_points(|tau| truth.avar(tau).unwrap(), 1_000_000);
        let mut problem = Problem::new(&points, &[find(id::GAUSS_MARKOV).unwrap()]).unwrap();
        let start = problem.initial_shapes();
        let shapes = problem.search_shapes(start, 3).unwrap();
        let t = shapes[0].exp();
        assert!((t / 0.5 - 1.0).abs() < 1e-3, "T = {t}");
        // The columns muted during the stagewise round all take part again afterwards.
        assert!(problem.muted.is_empty());
    }
}

//! Time-domain estimators: effects located in time or driven by another signal.
//!
//! A bias step or a noise burst has no τ-law (its Allan signature depends on where it sits in the
//! record), and temperature or g-sensitivity is best measured against the signal that drives it.
//! So these effects are estimated on the rate samples, and removed from them before the Allan fit
//! of the rest. The estimators are chosen by the effect's contract id (DESIGN §4); every value
//! goes through the effect's `build`, which validates it.
//!
//! Estimation order: the regressions first (temperature, g-sensitivity: they explain the slow and
//! the vibration parts a step or burst search would otherwise mistake), then the step, then the
//! burst (the burst search looks at sample-to-sample differences, which a step barely touches).

use crate::model::effects::EffectKind;
use crate::model::fit::{AxisInput, FitError};

/// What an estimator found: values in the effect's schema order, 1σ where known.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Parameter values in schema order, SI.
    pub values: Vec<f64>,
    /// 1σ uncertainties in schema order.
    pub sigmas: Vec<Option<f64>>,
    /// True when the effect is located in time (reported as an event).
    pub is_event: bool,
    /// A log-likelihood-ratio-like strength of the detection (≥ 0), for the diagnosis.
    pub strength: f64,
}

const ORDER: [&str; 4] = ["temperature", "g_sensitivity", "bias_step", "noise_burst"];

/// The time-domain kinds sorted in estimation order (unknown ids last, in the order given).
pub fn in_estimation_order(kinds: &[&'static dyn EffectKind]) -> Vec<&'static dyn EffectKind> {
    let rank = |k: &&'static dyn EffectKind| ORDER.iter().position(|&id| id == k.id()).unwrap_or(ORDER.len());
    let mut v = kinds.to_vec();
    v.sort_by_key(rank);
    v
}

/// True when the recording carries the evidence `kind` needs on this axis.
pub fn has_evidence(kind: &dyn EffectKind, input: &AxisInput<'_>) -> bool {
    match kind.id() {
        "temperature" => input.temperature_c.is_some(),
        "g_sensitivity" => input.accel.is_some() && input.axis.is_gyro(),
        _ => true,
    }
}

/// Estimates a time-domain effect on `series` (the axis's rate, with earlier effects removed).
///
/// # Errors
/// [`FitError::MissingEvidence`] without the driving signal; [`FitError::NoEstimator`] for an id
/// this module does not know.
pub fn estimate(
    kind: &'static dyn EffectKind,
    input: &AxisInput<'_>,
    series: &[f64],
) -> Result<Estimate, FitError> {
    let missing = |needs| FitError::MissingEvidence {
        axis: input.axis.name(),
        effect: kind.id(),
        needs,
    };
    match kind.id() {
        "temperature" => {
            let t = input.temperature_c.ok_or_else(|| missing("a temperature topic"))?;
            let (c, s, _) = regress(series, t);
            let (_, _, strength) = regress_slow(series, t);
            Ok(Estimate { values: vec![c], sigmas: vec![Some(s)], is_event: false, strength })
        }
        "g_sensitivity" => {
            let acc = input
                .accel
                .filter(|_| input.axis.is_gyro())
                .ok_or_else(|| missing("the accelerometer axes of the same IMU (gyro axes only)"))?;
            let best = (0..3)
                .map(|src| (src, regress(series, acc[src])))
                .max_by(|a, b| a.1 .2.total_cmp(&b.1 .2))
                .unwrap_or((0, (0.0, 0.0, 0.0)));
            let (src, (c, s, strength)) = best;
            Ok(Estimate {
                values: vec![src as f64, c],
                sigmas: vec![None, Some(s)],
                is_event: false,
                strength,
            })
        }
        "bias_step" => {
            let (i, size, strength) = find_step(series);
            Ok(Estimate {
                values: vec![i as f64 * input.tau0, size],
                sigmas: vec![None, None],
                is_event: true,
                strength,
            })
        }
        "noise_burst" => {
            let b = find_burst(series, input.tau0);
            Ok(Estimate {
                values: vec![b.start as f64 * input.tau0, b.end as f64 * input.tau0, b.factor.max(1.0)],
                sigmas: vec![None, None, None],
                is_event: true,
                strength: b.strength,
            })
        }
        _ => Err(FitError::NoEstimator(kind.id())),
    }
}

/// Removes an estimated effect from `series`.
pub fn remove(kind: &dyn EffectKind, est: &Estimate, input: &AxisInput<'_>, series: &mut [f64]) {
    let v = &est.values;
    match kind.id() {
        "temperature" => {
            if let Some(t) = input.temperature_c {
                let mean = finite_mean(t);
                series.iter_mut().zip(t).for_each(|(y, c)| *y -= v[0] * (c - mean));
            }
        }
        "g_sensitivity" => {
            if let Some(acc) = input.accel {
                let src = acc[(v[0].round() as usize).min(2)];
                let mean = finite_mean(src);
                series.iter_mut().zip(src).for_each(|(y, a)| *y -= v[1] * (a - mean));
            }
        }
        "bias_step" => {
            let start = (v[0] / input.tau0).round() as usize;
            series.iter_mut().skip(start).for_each(|y| *y -= v[1]);
        }
        "noise_burst" => {
            let start = (v[0] / input.tau0).round() as usize;
            let end = ((v[1] / input.tau0).round() as usize).min(series.len());
            shrink_white(&mut series[start.min(end)..end], v[2], block_len(input.tau0));
        }
        _ => {}
    }
}

fn finite_mean(x: &[f64]) -> f64 {
    let (s, n) = x
        .iter()
        .filter(|v| v.is_finite())
        .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n > 0 {
        s / n as f64
    } else {
        0.0
    }
}

/// A least-squares line y = a + b·x through points added one at a time (Welford updates): the
/// whole-record regressions here and the node's live temperature coefficient share it.
///
/// # Formula
/// ```text
/// b = Sxy / Sxx,   σ_b² = (Syy − b·Sxy) / ((n − 2)·Sxx)
/// ```
/// with Sxx, Sxy, Syy the sums of products of deviations from the running means.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LineFit {
    n: u64,
    mean_x: f64,
    mean_y: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
}

impl LineFit {
    /// Adds the point (x, y).
    pub fn add(&mut self, x: f64, y: f64) {
        self.n += 1;
        let n = self.n as f64;
        let dx = x - self.mean_x;
        let dy = y - self.mean_y;
        self.mean_x += dx / n;
        self.mean_y += dy / n;
        self.sxx += dx * (x - self.mean_x);
        self.sxy += dx * (y - self.mean_y);
        self.syy += dy * (y - self.mean_y);
    }

    /// Points added.
    pub fn len(&self) -> u64 {
        self.n
    }

    /// True before the first point.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// (slope, its standard error), once there are three points and x moved.
    pub fn slope(&self) -> Option<(f64, f64)> {
        if self.n < 3 || self.sxx <= 0.0 {
            return None;
        }
        let b = self.sxy / self.sxx;
        let residual = (self.syy - b * self.sxy).max(0.0) / (self.n - 2) as f64;
        Some((b, (residual / self.sxx).sqrt()))
    }
}

/// Least-squares slope of `y` on `x` (both demeaned, NaN pairs skipped), its standard error, and
/// the squared t statistic (the strength): a [`LineFit`] through the pairs.
///
/// # Formula
/// ```text
/// c = Σ (x−x̄)(y−ȳ) / Σ (x−x̄)²,   se² = Σ r² / ((n−2)·Σ (x−x̄)²),   strength = (c/se)²
/// ```
pub fn regress(y: &[f64], x: &[f64]) -> (f64, f64, f64) {
    let mut line = LineFit::default();
    y.iter()
        .zip(x)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .for_each(|(&a, &b)| line.add(b, a));
    let Some((c, se)) = line.slope() else {
        return (0.0, f64::INFINITY, 0.0);
    };
    let strength = if se > 0.0 { (c / se).powi(2) } else { f64::INFINITY };
    (c, se, strength)
}

/// Least-squares slope between the first differences of coarse block means (record/20 per
/// block), its standard error corrected for the lag-1 autocorrelation ρ ≥ 0 of the residuals,
/// and the squared t statistic: the significance of a slow driver such as temperature.
///
/// Why differences: a temperature drifts over minutes, where the sensor's random walk lives too,
/// and a regression of one smooth curve on another has about one degree of freedom whatever the
/// number of samples (a "spurious regression"). Differencing turns a random walk into white
/// increments; the levels are kept for the coefficient itself (efficient when the effect is
/// strong), the differences only decide whether it is real.
///
/// # Formula
/// ```text
/// Δȳₖ = ȳₖ₊₁ − ȳₖ,  Δx̄ₖ = x̄ₖ₊₁ − x̄ₖ,   c = OLS slope of Δȳ on Δx̄
/// se_eff = se·√((1+ρ)/(1−ρ)),   strength = (c/se_eff)²
/// ```
pub fn regress_slow(y: &[f64], x: &[f64]) -> (f64, f64, f64) {
    let block = (y.len() / 20).max(1);
    let ym: Vec<f64> = y.chunks(block).map(finite_mean).collect();
    let xm: Vec<f64> = x.chunks(block).map(finite_mean).collect();
    let dy: Vec<f64> = ym.windows(2).map(|w| w[1] - w[0]).collect();
    let dx: Vec<f64> = xm.windows(2).map(|w| w[1] - w[0]).collect();
    let (c, se, _) = regress(&dy, &dx);
    let (mx, my) = (finite_mean(&dx), finite_mean(&dy));
    let r: Vec<f64> = dy.iter().zip(&dx).map(|(a, b)| (a - my) - c * (b - mx)).collect();
    let var: f64 = r.iter().map(|v| v * v).sum();
    let lag: f64 = r.windows(2).map(|w| w[0] * w[1]).sum();
    let rho = if var > 0.0 { (lag / var).clamp(0.0, 0.95) } else { 0.0 };
    let se_eff = se * ((1.0 + rho) / (1.0 - rho)).sqrt();
    let strength = if se_eff > 0.0 { (c / se_eff).powi(2) } else { 0.0 };
    (c, se_eff, strength)
}

/// Whether a time-domain estimate is significant on its own evidence.
///
/// Thresholds on the estimators' statistics: a regression's t² above 25 (5σ), a step contrast
/// above 40 times its robust variance (6.3σ: the maximum over ~n/W positions of a χ²₁ stays far
/// below), a burst's likelihood ratio above 30.
pub fn is_significant(kind: &dyn EffectKind, est: &Estimate) -> bool {
    let threshold = match kind.id() {
        "temperature" | "g_sensitivity" => 25.0,
        "bias_step" => 40.0,
        "noise_burst" => 30.0,
        _ => return false,
    };
    est.strength > threshold
}

/// Samples per block for windowed statistics: about one second, at least 8 samples.
fn block_len(tau0: f64) -> usize {
    ((1.0 / tau0).round() as usize).max(8)
}

/// The most likely single step in the mean: local two-window contrast, maximised.
///
/// Returns (first sample after the step, size, strength = contrast² / its robust typical value).
///
/// # Formula
/// ```text
/// D(i) = mean(y[i..i+W]) − mean(y[i−W..i]),   i* = argmax |D(i)|,   size = D(i*)
/// ```
/// W = n/30 samples: long enough to average the white noise, short enough that a random walk
/// does not look like a step.
pub fn find_step(y: &[f64]) -> (usize, f64, f64) {
    let n = y.len();
    let w = (n / 30).max(2);
    if n < 2 * w + 1 {
        return (0, 0.0, 0.0);
    }
    let mut prefix = Vec::with_capacity(n + 1);
    let mut acc = 0.0;
    prefix.push(0.0);
    for &v in y {
        acc += if v.is_finite() { v } else { 0.0 };
        prefix.push(acc);
    }
    let wf = w as f64;
    let contrast = |i: usize| (prefix[i + w] - prefix[i]) / wf - (prefix[i] - prefix[i - w]) / wf;
    let (best_i, best_d) = (w..=n - w)
        .map(|i| (i, contrast(i)))
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap_or((0, 0.0));
    // E[D²] = 2σ²_A(W·τ0) for stationary noise; estimated robustly from the median of D² on a
    // grid of positions (a step touches only 2W of them): median(χ²₁) = 0.4549.
    let mut d2: Vec<f64> = (w..=n - w).step_by((w / 4).max(1)).map(|i| contrast(i).powi(2)).collect();
    d2.sort_by(f64::total_cmp);
    let typical = d2.get(d2.len() / 2).copied().unwrap_or(0.0) / 0.4549;
    let strength = if typical > 0.0 { best_d * best_d / typical } else { 0.0 };
    (best_i, best_d, strength)
}

/// A span where the white level is higher than elsewhere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Burst {
    /// First sample inside.
    pub start: usize,
    /// First sample after.
    pub end: usize,
    /// Ratio of white standard deviations inside / outside.
    pub factor: f64,
    /// Log-likelihood ratio against "no burst".
    pub strength: f64,
}

impl Burst {
    /// No burst: an empty span, factor 1, strength 0.
    pub const NONE: Burst = Burst { start: 0, end: 0, factor: 1.0, strength: 0.0 };
}

/// Finds the one span whose white-noise level differs most, by a Gaussian likelihood ratio on
/// per-block variances of first differences (slow effects cancel in the differences).
///
/// The search is exact and costs O(nb·h) instead of the O(nb²) of scoring every span: LLR is a
/// convex function of the span's point (n_in, V_in), and every span is a difference of two points
/// of the cumulative path Pₖ = (Σ_{j<k} n_j, Σ_{j<k} v_j). For a fixed start s, a convex function
/// of P_e − P_s takes its maximum over e > s at a vertex of the convex hull of {P_e : e > s}; the
/// lower and upper hulls of those suffixes are kept on two stacks while s walks backwards (Andrew's
/// monotone chain: each point pushed and popped once). h, the number of hull vertices, is that of
/// the convex minorant plus the concave majorant of a random walk: about 2·ln nb for noise, so the
/// search is O(nb log nb) on data (13 h of 1 s blocks: 1.1·10⁹ spans scored before, issue 11).
///
/// # Formula
/// ```text
/// vₖ = Σ_{block k} (y[i+1] − y[i])² / 2        (b samples per block)
/// LLR(s, e) = ½·[n·ln(V/n) − n_in·ln(V_in/n_in) − n_out·ln(V_out/n_out)]
/// ```
/// maximised over block spans [s, e), where V sums vₖ and n counts differences. n·ln(V/n) is the
/// perspective of ln, concave in (n, V), so LLR is convex wherever V_in, V_out > 0 (a span of
/// exactly constant samples, V_in = 0 with n_in > 0, is the one case the hull may miss). LLR ≥ 0
/// and is 0 for the whole record, so leaving that span out never hides a better one.
///
/// # References
/// S. Boyd, L. Vandenberghe, Convex Optimization, Cambridge University Press, 2004, §3.2.6
/// (perspective). A. M. Andrew, "Another efficient algorithm for convex hulls in two dimensions",
/// Information Processing Letters 9(5), 1979. P. Groeneboom, "The concave majorant of Brownian
/// motion", Annals of Probability 11(4), 1983 (the logarithmic vertex count).
pub fn find_burst(y: &[f64], tau0: f64) -> Burst {
    let Some(path) = VariancePath::new(y, block_len(tau0)) else {
        return Burst::NONE;
    };
    let nb = path.blocks();
    let (pc, pv) = (&path.pc, &path.pv);
    // (b − a) × (c − a) on path points: > 0 when a → b → c turns left.
    let cross = |a: usize, b: usize, c: usize| {
        (pc[b] - pc[a]) * (pv[c] - pv[a]) - (pv[b] - pv[a]) * (pc[c] - pc[a])
    };
    // Stacks of path indices, the newest (leftmost) point on top. Collinear and repeated points
    // are dropped (a convex function on a segment peaks at an end), the lower index kept.
    let (mut lower, mut upper): (Vec<usize>, Vec<usize>) = (Vec::new(), Vec::new());
    let mut best = Burst::NONE;
    let mut best_span = (usize::MAX, usize::MAX);
    for s in (0..nb).rev() {
        let p = s + 1;
        while lower.len() >= 2 && cross(p, lower[lower.len() - 1], lower[lower.len() - 2]) <= 0.0 {
            lower.pop();
        }
        lower.push(p);
        while upper.len() >= 2 && cross(p, upper[upper.len() - 1], upper[upper.len() - 2]) >= 0.0 {
            upper.pop();
        }
        upper.push(p);
        for &e in lower.iter().chain(&upper) {
            let Some(burst) = path.score(s, e) else { continue };
            // Ties go to the earliest span, as a scan in (s, e) order would report.
            let tie = burst.strength == best.strength && (s, e) < best_span;
            if burst.strength > best.strength || (tie && burst.strength > 0.0) {
                best = burst;
                best_span = (s, e);
            }
        }
    }
    best
}

/// The cumulative path of per-block half squared first differences and their counts, the input
/// of [`find_burst`].
struct VariancePath {
    /// Samples per block.
    b: usize,
    /// Σ vⱼ for j < k, k = 0..=nb.
    pv: Vec<f64>,
    /// Σ nⱼ for j < k.
    pc: Vec<f64>,
    /// n·ln(V/n) of the whole record.
    total: f64,
}

impl VariancePath {
    /// The path of `y` in blocks of `b` samples; `None` under 4 blocks or without spread.
    fn new(y: &[f64], b: usize) -> Option<Self> {
        let nb = y.len() / b;
        if nb < 4 {
            return None;
        }
        let (mut pv, mut pc) = (Vec::with_capacity(nb + 1), Vec::with_capacity(nb + 1));
        let (mut sv, mut sc) = (0.0, 0.0);
        pv.push(sv);
        pc.push(sc);
        for k in 0..nb {
            let blk = &y[k * b..((k + 1) * b + 1).min(y.len())];
            let (s, n) = blk
                .windows(2)
                .filter(|p| p[0].is_finite() && p[1].is_finite())
                .fold((0.0, 0usize), |(s, n), p| (s + 0.5 * (p[1] - p[0]).powi(2), n + 1));
            sv += s;
            sc += n as f64;
            pv.push(sv);
            pc.push(sc);
        }
        if sv <= 0.0 || sc <= 0.0 {
            return None;
        }
        Some(VariancePath { b, pv, pc, total: ll(sv, sc) })
    }

    fn blocks(&self) -> usize {
        self.pv.len() - 1
    }

    /// The span of blocks [s, e) as a burst; `None` for the whole record or an empty side.
    fn score(&self, s: usize, e: usize) -> Option<Burst> {
        let nb = self.blocks();
        let (vt, ct) = (self.pv[nb], self.pc[nb]);
        let (vi, ci) = (self.pv[e] - self.pv[s], self.pc[e] - self.pc[s]);
        let (vo, co) = (vt - vi, ct - ci);
        if e - s == nb || ci <= 0.0 || co <= 0.0 {
            return None;
        }
        Some(Burst {
            start: s * self.b,
            end: e * self.b,
            factor: ((vi / ci) / (vo / co)).sqrt(),
            strength: 0.5 * (self.total - ll(vi, ci) - ll(vo, co)),
        })
    }
}

/// n·ln(V/n), 0 for an empty or constant part.
fn ll(v: f64, n: f64) -> f64 {
    if n > 0.0 && v > 0.0 {
        n * (v / n).ln()
    } else {
        0.0
    }
}

/// Scales the fast part of `span` down by `factor` around a 30 s moving mean (the slow part).
fn shrink_white(span: &mut [f64], factor: f64, block: usize) {
    if factor <= 1.0 || span.is_empty() {
        return;
    }
    let half = (15 * block).max(1);
    let mut prefix = Vec::with_capacity(span.len() + 1);
    let mut acc = 0.0;
    prefix.push(0.0);
    for &v in span.iter() {
        acc += if v.is_finite() { v } else { 0.0 };
        prefix.push(acc);
    }
    let n = span.len();
    for (i, y) in span.iter_mut().enumerate() {
        let (lo, hi) = (i.saturating_sub(half), (i + half + 1).min(n));
        let mean = (prefix[hi] - prefix[lo]) / (hi - lo) as f64;
        *y = mean + (*y - mean) / factor;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
    }

    #[test]
    fn step_is_located_and_sized() {
        let mut y = noise(60_000, 1);
        y.iter_mut().skip(21_000).for_each(|v| *v += 0.3);
        let (i, size, strength) = find_step(&y);
        assert!((i as i64 - 21_000).abs() < 300, "{i}");
        // D's white-noise sd is √(2/W) = 0.032 with W = 2000.
        assert!((size - 0.3).abs() < 4.0 * (2.0f64 / 2000.0).sqrt(), "{size}");
        assert!(strength > 50.0);
    }

    #[test]
    fn burst_is_located_and_sized() {
        let mut y = noise(100 * 1200, 2);
        let extra = noise(100 * 1200, 3);
        for i in 30_000..50_000 {
            y[i] += extra[i] * (9.0f64 - 1.0).sqrt();
        }
        let b = find_burst(&y, 0.01);
        assert!((b.start as i64 - 30_000).abs() <= 100 && (b.end as i64 - 50_000).abs() <= 100, "{b:?}");
        assert!((b.factor - 3.0).abs() < 0.1, "{b:?}");
    }

    /// The definition: every span of blocks scored, the first maximum kept.
    fn burst_by_all_spans(y: &[f64], tau0: f64) -> Burst {
        let Some(path) = VariancePath::new(y, block_len(tau0)) else {
            return Burst::NONE;
        };
        let nb = path.blocks();
        let mut best = Burst::NONE;
        for s in 0..nb {
            for e in s + 1..=nb {
                match path.score(s, e) {
                    Some(b) if b.strength > best.strength => best = b,
                    _ => {}
                }
            }
        }
        best
    }

    #[test]
    fn hull_search_equals_the_search_over_every_span() {
        // Seeded records of 2–20 min at 100 Hz: plain noise, bursts and quiet spans of every
        // length and place, a noise level ramping over the record, NaN runs, a leading gap.
        for seed in 0..40u64 {
            let n = 100 * (120 + 60 * (seed as usize % 19));
            let mut y = noise(n, 100 + seed);
            let extra = noise(n, 200 + seed);
            let (a, len) = ((seed as usize * 7919) % n, 100 * (1 + (seed as usize * 31) % 300));
            let factor = [1.0, 3.0, 0.5, 1.3, 1.1][seed as usize % 5];
            for i in a..(a + len).min(n) {
                y[i] = y[i] * factor + 0.1 * extra[i];
            }
            if seed % 4 == 1 {
                y.iter_mut().enumerate().for_each(|(i, v)| *v *= 1.0 + i as f64 / n as f64);
            }
            if seed % 6 == 2 {
                y[..350].iter_mut().for_each(|v| *v = f64::NAN);
                y[n / 2..n / 2 + 700].iter_mut().for_each(|v| *v = f64::NAN);
            }
            let (fast, slow) = (find_burst(&y, 0.01), burst_by_all_spans(&y, 0.01));
            assert_eq!(fast, slow, "seed {seed}");
        }
    }

    #[test]
    fn regression_recovers_slope_with_honest_error() {
        let x: Vec<f64> = (0..5000).map(|i| (i as f64 * 0.01).sin()).collect();
        let e = noise(5000, 4);
        let y: Vec<f64> = x.iter().zip(&e).map(|(a, b)| 2.0 * a + b).collect();
        let (c, se, _) = regress(&y, &x);
        assert!((c - 2.0).abs() < 4.0 * se, "{c} ± {se}");
        assert!(se > 0.01 && se < 0.05);
    }
}

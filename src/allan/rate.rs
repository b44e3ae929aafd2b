//! Overlapping Allan variance of IMU rate data in which NaN marks an invalid or missing sample.
//!
//! IMU records have gaps, dropped messages and bad values (docs/design.md §1). Rather than bridging them,
//! every Allan term whose 2m rate samples include an invalid one is left out and counted, so the
//! estimate uses only real data and the caller can publish how much was dropped.
//!
//! A record that loses a message every few seconds (a robot's network dropping 0.5 % of its
//! packets) then has no term at all above the spacing of its holes, and no long-τ estimate:
//! [`oavar_rate_bridged`] is for the fit, which needs one. Only at factors where the rule above
//! leaves out most terms, it averages each half of a term over the samples it holds, as long as
//! hardly any is missing (after Sesia & Tavella 2008, who average over the available data).
//!
//! EDF: the noise type is identified on the record with its invalid samples removed (the valid
//! pieces joined), and Greenhall's EDF is evaluated for a gap-free record giving the same number of
//! terms (N = terms + 2m phase points). This is exact without gaps and a slight overstatement of
//! the EDF with them (fewer, not independent, terms are lost than a shorter record would lose).

use super::{noise_id, with_confidence, AllanPoint, Estimator};

/// An overlapping Allan estimate on rate data, with the count of terms left out.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RatePoint {
    /// The estimate; `terms` counts the terms used.
    pub point: AllanPoint,
    /// Terms left out because they touched an invalid (NaN or infinite) sample.
    pub skipped: usize,
    /// The identified power-law exponent α, `None` if it could not be identified (EDF then uses α = 0).
    pub alpha: Option<i32>,
    /// True when the terms were bridged over missing samples ([`oavar_rate_bridged`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub bridged: bool,
}

/// Overlapping Allan variance of rate data `rate` (NaN = invalid), with EDF and 68.3 % interval.
///
/// Same as [`oavar_rate_counted`] without the counts. Factors with no valid term are left out.
///
/// ```
/// let rate = [892.0, 809.0, 823.0, 798.0, 671.0, 644.0, 883.0, 903.0, 677.0]; // NBS-14 frequency
/// let p = fdavar::allan::oavar_rate(&rate, 1.0, &[1, 2]);
/// assert!((p[0].adev() - 91.22945).abs() < 1e-4);
/// assert!((p[1].adev() - 85.95287).abs() < 1e-4);
/// ```
pub fn oavar_rate(rate: &[f64], tau0: f64, factors: &[usize]) -> Vec<AllanPoint> {
    oavar_rate_counted(rate, tau0, factors)
        .into_iter()
        .map(|r| r.point)
        .collect()
}

/// Overlapping Allan variance of rate data, leaving out and counting terms that touch invalid samples.
///
/// Use this for IMU axes: `rate[n]` is one sample (rad/s or m/s²) at period `tau0` seconds, NaN or
/// ±∞ where the sample is missing or bad. A non-positive or non-finite `tau0` gives no points.
///
/// # Formula
/// ```text
/// x[n] = τ0·Σ_{k<n} (y[k] − y₀)   (invalid y counted as y₀, the first valid sample)
/// σ²(τ) = Σ_{i valid} (x[i+2m] − 2·x[i+m] + x[i])² / (2·τ²·terms),   τ = m·τ0
/// ```
/// where term i is valid when y[i .. i+2m] holds no invalid sample; subtracting y₀ changes no
/// term and keeps the phase of a biased axis small (the streaming accumulator does the same, so
/// the two agree exactly).
///
/// ```
/// let mut rate = vec![1.0, -1.0, 2.0, 0.5, -0.5, 1.5, 0.0, 1.0];
/// rate[3] = f64::NAN;
/// let p = fdavar::allan::oavar_rate_counted(&rate, 1.0, &[1]);
/// assert_eq!((p[0].point.terms, p[0].skipped), (5, 2));
/// ```
pub fn oavar_rate_counted(rate: &[f64], tau0: f64, factors: &[usize]) -> Vec<RatePoint> {
    rate_points(rate, tau0, factors, false, Confidence::Identified, &mut Vec::new())
}

/// Most a bridged half of a term may miss, as a fraction of its m samples.
///
/// Why 2 %: a half averaged over v < m white-noise samples has variance σ²/v, so a term's
/// expectation rises by at most m/v − 1 ≈ 2 % at the limit, well inside the 1σ interval of any
/// long-τ estimate (a 1 h record has at most a few hundred independent terms at τ ≥ 10 s); at the
/// long τ that need bridging the noise is flicker or random walk, whose half-means a few missing
/// samples hardly move.
pub const BRIDGE_MAX_MISSING: f64 = 0.02;

/// [`oavar_rate_counted`], but at a factor where the gap rule leaves out more terms than it keeps,
/// the terms are bridged over missing samples.
///
/// Use this where an estimate at every τ matters more than the strict rule (the fit's measured
/// Allan variance): a record with a short hole every few seconds keeps its long τ. Without invalid
/// samples, or where the rule keeps most terms, the points are [`oavar_rate_counted`]'s, bit for bit.
///
/// # Formula
/// A bridged term averages each half over the samples it holds, with v₁, v₂ of its m samples
/// valid (at most [`BRIDGE_MAX_MISSING`]·m missing from each, else the term is left out):
/// ```text
/// ȳ₁ = mean of the valid y[i .. i+m],   ȳ₂ = mean of the valid y[i+m .. i+2m]
/// σ²(τ) = Σ_{i bridged} (ȳ₂ − ȳ₁)² / (2·terms)
/// ```
/// which is the strict term where no sample is missing (ȳ₂ − ȳ₁ is the second difference of the phase over τ).
///
/// # Reference
/// Sesia I., Tavella P., "Estimating the Allan variance in the presence of long periods of
/// missing data and outliers", Metrologia 45 (2008) S134; the bias of such averages for strongly
/// gapped data: Sesia I., Galleani L., Tavella P., IEEE TUFFC 66(10) (2019) 1667.
///
/// ```
/// let mut rate: Vec<f64> = (0..4000).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
/// for at in (100..4000).step_by(200) {
///     rate[at] = f64::NAN; // one sample lost every 200
/// }
/// let strict = fdavar::allan::oavar_rate_counted(&rate, 1.0, &[10, 500]);
/// let bridged = fdavar::allan::oavar_rate_bridged(&rate, 1.0, &[10, 500]);
/// assert_eq!(strict.len(), 1); // no term of 1000 samples avoids every hole
/// assert_eq!(bridged[0], strict[0]); // m = 10 keeps most terms: the same point
/// assert!(bridged[1].bridged && bridged[1].point.terms > 2900);
/// ```
pub fn oavar_rate_bridged(rate: &[f64], tau0: f64, factors: &[usize]) -> Vec<RatePoint> {
    oavar_rate_bridged_in(rate, tau0, factors, &mut Vec::new())
}

/// [`oavar_rate_bridged`] building the phase in `phase` (its contents are replaced), so that
/// measurements one after the other reuse one buffer.
///
/// Why: the fit measures the whole record and then each of its spans; a fresh buffer for each is
/// fresh pages from the kernel, zeroed and faulted in, for every one of them (in the node,
/// buffers of a series' size get mappings of their own: `analysis::return_large_buffers_to_kernel`).
pub fn oavar_rate_bridged_in(rate: &[f64], tau0: f64, factors: &[usize], phase: &mut Vec<f64>) -> Vec<RatePoint> {
    rate_points(rate, tau0, factors, true, Confidence::Identified, phase)
}

/// [`oavar_rate_bridged_in`] without the noise identification: σ² and its count of terms, with
/// `edf`, `ci_low` and `ci_high` NaN and no `alpha`.
///
/// Use it where the EDF of each τ comes from elsewhere: the fit weighs each τ by the EDF of its
/// model's noise mix ([`crate::model::measure::edf_for_mix`]), never by the noise identified in
/// the data.
///
/// Why: identifying the noise type at every τ (lag-1 autocorrelation passes over the decimated
/// record), Greenhall's EDF and the χ² interval cost the fit more than the variances themselves,
/// for the record and each of its spans, on numbers nothing read (docs/performance.md has the
/// measured share).
pub fn oavar_rate_bridged_variances_in(rate: &[f64], tau0: f64, factors: &[usize], phase: &mut Vec<f64>) -> Vec<RatePoint> {
    rate_points(rate, tau0, factors, true, Confidence::Skipped, phase)
}

/// [`oavar_rate_bridged_variances_in`] of the record `rate` at `factors` and of each span
/// `rate[range]` at its own factors, in one pass over the record's phase when no sample is invalid.
///
/// A term is the second difference of the phase over 2m samples, `x[i+2m] − 2x[i+m] + x[i] =
/// τ0·(Σ y[i+m .. i+2m] − Σ y[i .. i+m])`: it reads its own 2m samples only, so the span's term at
/// a sample is the record's term there (each integrates from its own first sample, an offset that
/// cancels). Each factor's terms are summed once per segment between the spans' ends, and the
/// record and each span add the segments they hold, in order.
///
/// Why: the fit measures the record and its half-overlapping spans (`model::fit::spans`), which
/// together hold each term about three times; summed once, the fit's measurement costs less than
/// half. The sums are the separate measurements' up to the order of the additions (relative
/// rounding 1e-16 per term). With invalid samples each span is measured on its own, as the
/// bridging rule decides per span.
pub fn oavar_rate_variances_with_spans_in(
    rate: &[f64],
    tau0: f64,
    factors: &[usize],
    spans: &[(std::ops::Range<usize>, Vec<usize>)],
    phase: &mut Vec<f64>,
) -> (Vec<RatePoint>, Vec<Vec<RatePoint>>) {
    let separately = |phase: &mut Vec<f64>| {
        let record = oavar_rate_bridged_variances_in(rate, tau0, factors, phase);
        let spans = spans
            .iter()
            .map(|(range, factors)| oavar_rate_bridged_variances_in(&rate[range.clone()], tau0, factors, phase))
            .collect();
        (record, spans)
    };
    if !(tau0.is_finite() && tau0 > 0.0) || rate.is_empty() || !rate.iter().all(|v| v.is_finite()) {
        return separately(phase);
    }
    // The record's phase, built in `phase` as the record's own measurement builds it.
    if rate_sums(rate, tau0, &[], false, phase).is_none() {
        return separately(phase);
    }
    let x: &[f64] = phase;
    // Each target: its samples and factors; at factor m it sums the terms [start, end) (its
    // phase has len + 1 points, its terms i ≤ len − 2m). Target 0 is the record.
    let targets: Vec<(std::ops::Range<usize>, &[usize])> = std::iter::once((0..rate.len(), factors))
        .chain(spans.iter().map(|(r, f)| (r.clone(), f.as_slice())))
        .collect();
    let mut sums: Vec<Vec<(usize, Terms)>> = vec![Vec::new(); targets.len()];
    let mut all: Vec<usize> = targets.iter().flat_map(|&(_, f)| f.iter().copied()).filter(|&m| m > 0).collect();
    all.sort_unstable();
    all.dedup();
    for m in all {
        let ranges: Vec<(usize, std::ops::Range<usize>)> = targets
            .iter()
            .enumerate()
            .filter(|(_, (samples, f))| f.contains(&m) && samples.len() + 1 > 2 * m)
            .map(|(t, (samples, _))| (t, samples.start..samples.end + 1 - 2 * m))
            .collect();
        let mut cuts: Vec<usize> = ranges.iter().flat_map(|(_, r)| [r.start, r.end]).collect();
        cuts.sort_unstable();
        cuts.dedup();
        let segments: Vec<(std::ops::Range<usize>, Terms)> =
            cuts.windows(2).map(|w| (w[0]..w[1], range_sums(x, &[], m, w[0]..w[1]))).collect();
        for (t, r) in ranges {
            let sum = segments
                .iter()
                .filter(|(s, _)| r.start <= s.start && s.end <= r.end)
                .fold(Terms::default(), |acc, (_, s)| Terms { sum: acc.sum + s.sum, terms: acc.terms + s.terms, skipped: 0 });
            sums[t].push((m, sum));
        }
    }
    let mut points = sums.into_iter().map(|t| {
        t.into_iter().filter_map(|(m, terms)| variance_point(m, tau0, terms, false)).collect::<Vec<_>>()
    });
    let record = points.next().unwrap_or_default();
    (record, points.collect())
}

/// The σ² point of factor `m` from its sums ([`Confidence::Skipped`]); `None` without a term.
fn variance_point(m: usize, tau0: f64, Terms { sum, terms, skipped }: Terms, bridged: bool) -> Option<RatePoint> {
    if terms == 0 {
        return None;
    }
    let tau = m as f64 * tau0;
    Some(RatePoint {
        point: AllanPoint {
            m,
            tau,
            avar: sum / (2.0 * tau * tau * terms as f64),
            terms,
            edf: f64::NAN,
            ci_low: f64::NAN,
            ci_high: f64::NAN,
        },
        skipped,
        alpha: None,
        bridged,
    })
}

/// What a measurement works out beyond σ² and its count of terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Confidence {
    /// The noise type at each τ, Greenhall's EDF for it and the 68.3 % interval.
    Identified,
    /// Nothing: `edf`, `ci_low` and `ci_high` NaN, `alpha` None.
    Skipped,
}

/// A record's strict or bridged sums ([`rate_sums`]).
struct RecordSums {
    /// The phase of the valid samples joined, when some sample is invalid (else the phase itself).
    joined: Option<Vec<f64>>,
    /// Per usable factor: m, its sums, whether bridged.
    sums: Vec<(usize, Terms, bool)>,
}

/// The points of [`oavar_rate_counted`] (`bridge` false) or [`oavar_rate_bridged`], the phase
/// built in `x`.
fn rate_points(
    rate: &[f64],
    tau0: f64,
    factors: &[usize],
    bridge: bool,
    confidence: Confidence,
    x: &mut Vec<f64>,
) -> Vec<RatePoint> {
    if !(tau0.is_finite() && tau0 > 0.0) {
        return Vec::new();
    }
    let Some(record) = rate_sums(rate, tau0, factors, bridge, x) else {
        return Vec::new();
    };
    let shape = Estimator::Oadev.shape();
    let mut alphas = vec![None; record.sums.len()];
    if confidence == Confidence::Identified {
        // One job per factor with terms, neighbouring factors side by side (`identify_each`).
        let phase = record.joined.as_deref().unwrap_or(x);
        let (at, jobs): (Vec<usize>, Vec<noise_id::IdJob>) = record
            .sums
            .iter()
            .enumerate()
            .filter(|(_, &(_, Terms { terms, .. }, _))| terms > 0)
            .map(|(i, &(m, Terms { terms, .. }, _))| (i, noise_id::IdJob { x: phase, m, terms }))
            .unzip();
        for (i, id) in at.into_iter().zip(noise_id::identify_each(&jobs, shape.d)) {
            alphas[i] = id.map(|(a, _)| a);
        }
    }
    record
        .sums
        .into_iter()
        .zip(alphas)
        .filter_map(|((m, Terms { sum, terms, skipped }, bridged), alpha)| {
            if terms == 0 {
                return None;
            }
            let sums = Terms { sum, terms, skipped };
            if confidence == Confidence::Skipped {
                return variance_point(m, tau0, sums, bridged);
            }
            let tau = m as f64 * tau0;
            let avar = sum / (2.0 * tau * tau * terms as f64);
            let point = with_confidence(m, tau, avar, terms, alpha.unwrap_or(0), shape, terms + 2 * m, super::edf::ONE_SIGMA);
            Some(RatePoint { point, skipped, alpha, bridged })
        })
        .collect()
}

/// The phase of `rate` (built in `x`) and the strict or bridged sums of each usable factor;
/// `None` when no sample is valid.
fn rate_sums(rate: &[f64], tau0: f64, factors: &[usize], bridge: bool, x: &mut Vec<f64>) -> Option<RecordSums> {
    let reference = rate.iter().copied().find(|v| v.is_finite())?;
    // Built in place, without centred or valid-only copies of the record (a whole-run record
    // holds millions of samples): the same additions, in the same order, as [`super::naive::phase_from_rate`].
    let phase_of = |values: &mut dyn Iterator<Item = f64>, x: &mut Vec<f64>| {
        x.clear();
        x.reserve(rate.len() + 1);
        let mut acc = 0.0;
        x.push(acc);
        for y in values {
            acc += tau0 * y;
            x.push(acc);
        }
    };
    phase_of(&mut rate.iter().map(|&v| if v.is_finite() { v - reference } else { 0.0 }), x);
    let x: &[f64] = x;
    // bad[k] = number of invalid samples among rate[..k]; empty when none is (the common case:
    // a whole-run record holds millions of samples).
    let bad: Vec<usize> = if rate.iter().all(|v| v.is_finite()) {
        Vec::new()
    } else {
        std::iter::once(0)
            .chain(rate.iter().scan(0usize, |acc, v| {
                *acc += usize::from(!v.is_finite());
                Some(*acc)
            }))
            .collect()
    };
    // The phase of the valid samples joined: `x` itself when none is invalid.
    let joined = (!bad.is_empty()).then(|| {
        let mut joined = Vec::new();
        phase_of(&mut rate.iter().filter(|v| v.is_finite()).map(|v| v - reference), &mut joined);
        joined
    });
    let usable: Vec<usize> = factors
        .iter()
        .copied()
        .filter(|&m| m > 0 && x.len() > 2 * m)
        .collect();
    let sums = second_difference_sums(x, &bad, &usable);
    let sums = usable
        .iter()
        .zip(sums)
        .map(|(&m, strict)| {
            let bridged = bridge && strict.terms < strict.skipped;
            (m, if bridged { bridged_sums(x, &bad, m) } else { strict }, bridged)
        })
        .collect();
    Some(RecordSums { joined, sums })
}

/// The valid squared second differences of one factor: their sum, how many, how many left out.
#[derive(Debug, Clone, Copy, Default)]
struct Terms {
    sum: f64,
    terms: usize,
    skipped: usize,
}

/// The bridged [`Terms`] of factor `m` ([`oavar_rate_bridged`]): each half's sum of valid
/// samples is a phase difference (an invalid sample adds 0 to `x`), scaled to m samples.
fn bridged_sums(x: &[f64], bad: &[usize], m: usize) -> Terms {
    let allowed = (BRIDGE_MAX_MISSING * m as f64).floor() as usize;
    // The half [a, a+m) scaled to m samples: m/v·(x[a+m] − x[a]), None with too few samples.
    let half = |a: usize| {
        let missing = bad[a + m] - bad[a];
        (missing <= allowed && missing < m).then(|| (x[a + m] - x[a]) * (m as f64 / (m - missing) as f64))
    };
    let mut acc = Terms::default();
    for i in 0..x.len() - 2 * m {
        match (half(i), half(i + m)) {
            (Some(first), Some(second)) => {
                let d = second - first;
                acc.sum += d * d;
                acc.terms += 1;
            }
            _ => acc.skipped += 1,
        }
    }
    acc
}

/// Partial sums per factor: term i of a range goes to partial sum (i − start) mod [`INTERLEAVE`].
pub(super) const INTERLEAVE: usize = 8;

/// [`Terms`] of phase `x` at each factor of `factors` (each with x.len() > 2m), over
/// i = 0 … x.len() − 2m − 1. An empty `bad` or one that counts no invalid sample: every term
/// counts, and `bad` is not read.
fn second_difference_sums(x: &[f64], bad: &[usize], factors: &[usize]) -> Vec<Terms> {
    factors.iter().map(|&m| range_sums(x, bad, m, 0..x.len() - 2 * m)).collect()
}

/// [`Terms`] of factor `m` over the terms i ∈ `range` of phase `x` (`bad` as in
/// [`second_difference_sums`]), on the widest vector unit the CPU has.
///
/// Why interleaved: one running sum is a chain of dependent additions that waits on the adder's
/// latency at every term, and its terms cannot go through the vector units together. Term i is
/// added to partial sum (i − start) mod [`INTERLEAVE`], each partial sum in index order, and the
/// partial sums are added pairwise at the end ([`pairwise`]): eight independent chains that the
/// compiler lays out as vector lanes. The rounding is that of a sum in another order (relative
/// 1e-16 per term, as the plain loop's), and the same on every CPU: with AVX2 the same lanes go
/// four to a register instead of two, and neither path fuses a multiply with an add.
fn range_sums(x: &[f64], bad: &[usize], m: usize, range: std::ops::Range<usize>) -> Terms {
    let gap_free = bad.last().is_none_or(|&b| b == 0);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked on the line above.
        return unsafe {
            if gap_free {
                interleaved_avx2::<false>(x, &[], m, range)
            } else {
                interleaved_avx2::<true>(x, bad, m, range)
            }
        };
    }
    if gap_free {
        interleaved::<false>(x, &[], m, range)
    } else {
        interleaved::<true>(x, bad, m, range)
    }
}

/// [`interleaved`] compiled for AVX2 (four lanes per register instead of SSE2's two).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn interleaved_avx2<const CHECK: bool>(x: &[f64], bad: &[usize], m: usize, range: std::ops::Range<usize>) -> Terms {
    interleaved::<CHECK>(x, bad, m, range)
}

/// The sums of [`range_sums`]; `CHECK`: test each term's samples for validity
/// (`bad[i + 2m] == bad[i]`), branch-free so that the lanes stay vectors.
#[inline(always)]
fn interleaved<const CHECK: bool>(x: &[f64], bad: &[usize], m: usize, range: std::ops::Range<usize>) -> Terms {
    const K: usize = INTERLEAVE;
    let (lo, n) = (range.start, range.len());
    let whole = n - n % K;
    let (x0, x1, x2) = (&x[lo..lo + n], &x[lo + m..lo + m + n], &x[lo + 2 * m..lo + 2 * m + n]);
    let mut sum = [0.0f64; K];
    let mut terms = [0usize; K];
    let chunks = x0[..whole].chunks_exact(K).zip(x1[..whole].chunks_exact(K)).zip(x2[..whole].chunks_exact(K));
    let (b0, b2) = if CHECK { (&bad[lo..lo + n], &bad[lo + 2 * m..lo + 2 * m + n]) } else { (&[][..], &[][..]) };
    if CHECK {
        for (((a, b), c), (v0, v2)) in chunks.zip(b0[..whole].chunks_exact(K).zip(b2[..whole].chunks_exact(K))) {
            for k in 0..K {
                let d = c[k] - 2.0 * b[k] + a[k];
                let ok = v2[k] == v0[k];
                sum[k] += if ok { d * d } else { 0.0 };
                terms[k] += usize::from(ok);
            }
        }
    } else {
        // Two quads of lanes: the compiler then keeps each in one vector (with eight lanes at
        // once it split them 2 + 4 + 2 and gathered the ends element by element).
        let (mut low, mut high) = ([0.0f64; 4], [0.0f64; 4]);
        for ((a, b), c) in chunks {
            quad(&mut low, &a[..4], &b[..4], &c[..4]);
            quad(&mut high, &a[4..], &b[4..], &c[4..]);
        }
        sum = [low[0], low[1], low[2], low[3], high[0], high[1], high[2], high[3]];
    }
    for i in whole..n {
        let ok = !CHECK || b2[i] == b0[i];
        let d = x2[i] - 2.0 * x1[i] + x0[i];
        sum[i - whole] += if ok { d * d } else { 0.0 };
        terms[i - whole] += usize::from(ok);
    }
    let terms = if CHECK { terms.iter().sum() } else { n };
    Terms { sum: pairwise(sum), terms, skipped: n - terms }
}

/// Adds (c − 2b + a)² to four lanes.
#[inline(always)]
fn quad(acc: &mut [f64; 4], a: &[f64], b: &[f64], c: &[f64]) {
    let (a, b, c) = (&a[..4], &b[..4], &c[..4]);
    for k in 0..4 {
        let d = c[k] - 2.0 * b[k] + a[k];
        acc[k] += d * d;
    }
}

/// ((s0 + s1) + (s2 + s3)) + ((s4 + s5) + (s6 + s7)): the partial sums in a fixed order.
pub(super) fn pairwise(s: [f64; INTERLEAVE]) -> f64 {
    ((s[0] + s[1]) + (s[2] + s[3])) + ((s[4] + s[5]) + (s[6] + s[7]))
}

#[cfg(test)]
mod tests {
    use super::super::{naive, TauGrid};
    use super::*;
    use proptest::prelude::*;

    proptest! {
        // Without invalid samples the rate path equals the oracle on the integrated phase.
        #[test]
        fn equals_naive_without_gaps(y in prop::collection::vec(-10f64..10.0, 3..120), tau0 in 0.001f64..1.0) {
            let x = naive::phase_from_rate(&y, tau0);
            let factors: Vec<usize> = (1..=y.len() / 2).collect();
            let pts = oavar_rate_counted(&y, tau0, &factors);
            prop_assert_eq!(pts.len(), factors.len());
            for p in pts {
                let want = naive::oavar(&x, tau0, p.point.m).unwrap();
                prop_assert!((p.point.avar - want).abs() <= 1e-9 * want.max(1e-12), "m={}: {} vs {}", p.point.m, p.point.avar, want);
                prop_assert_eq!(p.skipped, 0);
            }
        }

        // With NaNs: the estimate equals the mean of the squared differences of the terms that
        // avoid every NaN, computed literally, and used + skipped = all terms.
        #[test]
        fn nan_terms_are_left_out(y in prop::collection::vec(-10f64..10.0, 8..80), holes in prop::collection::vec(0usize..80, 1..4)) {
            let mut y = y;
            let n = y.len();
            for h in &holes { y[h % n] = f64::NAN; }
            for p in oavar_rate_counted(&y, 1.0, &(1..=n / 2).collect::<Vec<_>>()) {
                let m = p.point.m;
                let mut terms = Vec::new();
                for i in 0..=n - 2 * m {
                    let w = &y[i..i + 2 * m];
                    if w.iter().all(|v| v.is_finite()) {
                        let a: f64 = w[m..].iter().sum::<f64>() - w[..m].iter().sum::<f64>();
                        terms.push(a * a / (2.0 * (m * m) as f64));
                    }
                }
                prop_assert_eq!(p.point.terms, terms.len());
                prop_assert_eq!(p.point.terms + p.skipped, n + 1 - 2 * m);
                let want = terms.iter().sum::<f64>() / terms.len() as f64;
                prop_assert!((p.point.avar - want).abs() <= 1e-9 * want.max(1e-12));
            }
        }

        // The interleaved sums are the plain loop's over i for each factor alone (with and
        // without invalid samples) up to the order of the additions; a record without invalid
        // samples gives the same bits whether `bad` is given or left empty, and a range's sums
        // are those of its terms alone.
        #[test]
        fn interleaved_sums_equal_the_plain_loop(y in prop::collection::vec(-10f64..10.0, 600..1400), holes in prop::collection::vec(0usize..1400, 0..3), pick in prop::collection::vec(1usize..300, 1..20), cut in 0usize..1400) {
            let mut y = y;
            let n = y.len();
            for h in &holes { y[h % n] = f64::NAN; }
            let mut factors: Vec<usize> = pick.into_iter().filter(|&m| 2 * m < n).collect();
            factors.sort_unstable();
            factors.dedup();
            let x: Vec<f64> = std::iter::once(0.0).chain(y.iter().scan(0.0, |acc, &v| {
                *acc += if v.is_finite() { v } else { 0.0 };
                Some(*acc)
            })).collect();
            let bad: Vec<usize> = std::iter::once(0).chain(y.iter().scan(0, |acc, v| {
                *acc += usize::from(!v.is_finite());
                Some(*acc)
            })).collect();
            let got = second_difference_sums(&x, &bad, &factors);
            let gap_free = bad.last() == Some(&0);
            let got_empty = gap_free.then(|| second_difference_sums(&x, &[], &factors));
            prop_assert!(got_empty.is_none_or(|e| e.iter().zip(&got).all(|(a, b)| a.sum.to_bits() == b.sum.to_bits() && a.terms == b.terms)));
            let plain = |m: usize, range: std::ops::Range<usize>| {
                let mut want = Terms::default();
                for i in range {
                    if bad[i + 2 * m] == bad[i] {
                        let d = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
                        want.sum += d * d;
                        want.terms += 1;
                    } else {
                        want.skipped += 1;
                    }
                }
                want
            };
            for (t, &m) in got.iter().zip(&factors) {
                let want = plain(m, 0..x.len() - 2 * m);
                prop_assert!((t.sum - want.sum).abs() <= 1e-13 * want.sum, "m = {}: {} vs {}", m, t.sum, want.sum);
                prop_assert_eq!((t.terms, t.skipped), (want.terms, want.skipped));
                let end = x.len() - 2 * m;
                let part = range_sums(&x, &bad, m, cut.min(end)..end);
                let want = plain(m, cut.min(end)..end);
                prop_assert!((part.sum - want.sum).abs() <= 1e-13 * want.sum);
                prop_assert_eq!((part.terms, part.skipped), (want.terms, want.skipped));
            }
        }

        // The AVX2 build of the kernel adds the same lanes in the same order as the baseline
        // build: the same bits on every CPU (on a CPU without AVX2 there is nothing to compare).
        #[test]
        fn avx2_and_baseline_sums_are_the_same_bits(y in prop::collection::vec(-10f64..10.0, 20..700), m in 1usize..9, hole in prop::option::of(0usize..700)) {
            let x: Vec<f64> = std::iter::once(0.0).chain(y.iter().scan(0.0, |acc, &v| { *acc += v; Some(*acc) })).collect();
            let bad: Vec<usize> = (0..x.len()).map(|k| usize::from(hole.is_some_and(|h| h % y.len() < k))).collect();
            prop_assume!(x.len() > 2 * m);
            let range = 0..x.len() - 2 * m;
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                for checked in [false, true] {
                    let (wide, base) = if checked {
                        // SAFETY: AVX2 is supported (checked above).
                        (unsafe { interleaved_avx2::<true>(&x, &bad, m, range.clone()) }, interleaved::<true>(&x, &bad, m, range.clone()))
                    } else {
                        // SAFETY: as above.
                        (unsafe { interleaved_avx2::<false>(&x, &[], m, range.clone()) }, interleaved::<false>(&x, &[], m, range.clone()))
                    };
                    prop_assert_eq!((wide.sum.to_bits(), wide.terms, wide.skipped), (base.sum.to_bits(), base.terms, base.skipped));
                }
            }
        }

        // Record and spans in one pass: each is its own measurement up to the order of the
        // additions, point for point; with an invalid sample, exactly the separate measurements.
        #[test]
        fn spans_in_one_pass_equal_their_own_measurements(y in prop::collection::vec(-10f64..10.0, 400..1200), bias in -1e3f64..1e3, parts in 2usize..6, hole in prop::option::of(0usize..1200)) {
            let mut y: Vec<f64> = y.iter().map(|v| v + bias).collect();
            let n = y.len();
            if let Some(h) = hole { y[h % n] = f64::NAN; }
            let grid = TauGrid::default();
            let factors = grid.factors(n / 3);
            let spans: Vec<(std::ops::Range<usize>, Vec<usize>)> = (0..2 * parts - 1)
                .map(|i| {
                    let r = i * n / (2 * parts)..(i + 2) * n / (2 * parts);
                    let f = grid.factors(r.len() / 3);
                    (r, f)
                })
                .collect();
            let (record, measured) = oavar_rate_variances_with_spans_in(&y, 0.01, &factors, &spans, &mut Vec::new());
            let own = |rate: &[f64], factors: &[usize]| oavar_rate_bridged_variances_in(rate, 0.01, factors, &mut Vec::new());
            let same = |got: &[RatePoint], want: &[RatePoint]| -> Result<(), TestCaseError> {
                prop_assert_eq!(got.len(), want.len());
                for (g, w) in got.iter().zip(want) {
                    prop_assert_eq!((g.point.m, g.point.terms, g.skipped, g.bridged), (w.point.m, w.point.terms, w.skipped, w.bridged));
                    if hole.is_some() {
                        prop_assert_eq!(g.point.avar.to_bits(), w.point.avar.to_bits());
                    } else {
                        prop_assert!((g.point.avar / w.point.avar - 1.0).abs() < 1e-9, "m = {}: {} vs {}", g.point.m, g.point.avar, w.point.avar);
                    }
                }
                Ok(())
            };
            same(&record, &own(&y, &factors))?;
            prop_assert_eq!(measured.len(), spans.len());
            for ((range, f), got) in spans.iter().zip(&measured) {
                same(got, &own(&y[range.clone()], f))?;
            }
        }
    }

    proptest! {
        // Bridged: each point is the strict one where the rule keeps most terms, and otherwise
        // the mean of the literal terms (ȳ₂ − ȳ₁)²/2 over the valid samples of each half, a half
        // missing at most BRIDGE_MAX_MISSING·m of its samples.
        #[test]
        fn bridged_points_are_the_literal_half_means(y in prop::collection::vec(-10f64..10.0, 400..900), every in 40usize..120, offset in 0usize..40) {
            let mut y = y;
            let n = y.len();
            for at in (offset..n).step_by(every) { y[at] = f64::NAN; }
            let factors: Vec<usize> = (1..=n / 3).step_by(7).collect();
            let strict = oavar_rate_counted(&y, 1.0, &factors);
            let bridged = oavar_rate_bridged(&y, 1.0, &factors);
            let mut k = 0;
            for &m in &factors {
                let s = strict.iter().find(|p| p.point.m == m);
                let b = bridged.iter().find(|p| p.point.m == m);
                if s.is_some_and(|s| s.point.terms >= s.skipped) {
                    prop_assert_eq!(b, s);
                    continue;
                }
                let allowed = (BRIDGE_MAX_MISSING * m as f64).floor() as usize;
                let half = |w: &[f64]| {
                    let valid: Vec<f64> = w.iter().copied().filter(|v| v.is_finite()).collect();
                    (m - valid.len() <= allowed && !valid.is_empty()).then(|| valid.iter().sum::<f64>() / valid.len() as f64)
                };
                let terms: Vec<f64> = (0..=n - 2 * m)
                    .filter_map(|i| Some((half(&y[i + m..i + 2 * m])? - half(&y[i..i + m])?).powi(2) / 2.0))
                    .collect();
                match b {
                    None => prop_assert!(terms.is_empty(), "m = {}", m),
                    Some(b) => {
                        k += 1;
                        prop_assert!(b.bridged);
                        prop_assert_eq!(b.point.terms, terms.len());
                        prop_assert_eq!(b.point.terms + b.skipped, n + 1 - 2 * m);
                        let want = terms.iter().sum::<f64>() / terms.len() as f64;
                        prop_assert!((b.point.avar - want).abs() <= 1e-9 * want, "m = {}: {} vs {}", m, b.point.avar, want);
                    }
                }
            }
            // Holes 40–120 samples apart: some factor up to n/3 always needs the bridge.
            prop_assert!(k > 0 || factors.iter().all(|&m| 2 * m < every), "no bridged factor");
        }
    }

    proptest! {
        // Without the noise identification, the variances are those of the full measurement,
        // bit for bit (with holes, bridged or not), and nothing else is made up.
        #[test]
        fn variances_alone_equal_the_full_measurement(y in prop::collection::vec(-10f64..10.0, 300..900), holes in prop::collection::vec(0usize..900, 0..6)) {
            let mut y = y;
            let n = y.len();
            for h in &holes { y[h % n] = f64::NAN; }
            let factors = TauGrid::default().factors(n / 3);
            let full = oavar_rate_bridged(&y, 0.01, &factors);
            let alone = oavar_rate_bridged_variances_in(&y, 0.01, &factors, &mut vec![f64::NAN; 3]);
            prop_assert_eq!(alone.len(), full.len());
            for (a, f) in alone.iter().zip(&full) {
                prop_assert_eq!((a.point.m, a.point.tau.to_bits(), a.point.avar.to_bits(), a.point.terms), (f.point.m, f.point.tau.to_bits(), f.point.avar.to_bits(), f.point.terms));
                prop_assert_eq!((a.skipped, a.bridged), (f.skipped, f.bridged));
                prop_assert!(a.alpha.is_none() && a.point.edf.is_nan() && a.point.ci_low.is_nan() && a.point.ci_high.is_nan());
            }
        }
    }

    #[test]
    fn a_reused_phase_buffer_gives_the_same_points() {
        // One buffer for a long record, then for a shorter one with a hole: whatever it held,
        // the points are those of a fresh buffer, bit for bit.
        let long: Vec<f64> = (0..5000).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let mut short: Vec<f64> = long[..3000].iter().map(|v| v * 0.5 + 1.0).collect();
        short[1234] = f64::NAN;
        let factors = [1, 2, 5, 10, 100, 900];
        let mut phase = vec![f64::NAN; 7];
        for rate in [&long[..], &short[..], &long[..]] {
            assert_eq!(oavar_rate_bridged_in(rate, 0.01, &factors, &mut phase), oavar_rate_bridged(rate, 0.01, &factors));
        }
    }

    #[test]
    fn all_invalid_or_bad_tau0_gives_nothing() {
        assert!(oavar_rate(&[f64::NAN; 10], 1.0, &[1]).is_empty());
        assert!(oavar_rate(&[1.0; 10], 0.0, &[1]).is_empty());
    }
}

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
            let tau = m as f64 * tau0;
            let avar = sum / (2.0 * tau * tau * terms as f64);
            let point = match confidence {
                Confidence::Identified => with_confidence(
                    m,
                    tau,
                    avar,
                    terms,
                    alpha.unwrap_or(0),
                    shape,
                    terms + 2 * m,
                    super::edf::ONE_SIGMA,
                ),
                Confidence::Skipped => AllanPoint {
                    m,
                    tau,
                    avar,
                    terms,
                    edf: f64::NAN,
                    ci_low: f64::NAN,
                    ci_high: f64::NAN,
                },
            };
            Some(RatePoint {
                point,
                skipped,
                alpha,
                bridged,
            })
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

impl Terms {
    /// Adds the term at `i` for factor `m` (left out when `bad` counts an invalid sample in it;
    /// an empty `bad`: no sample is invalid).
    #[inline(always)]
    fn add(&mut self, x: &[f64], bad: &[usize], m: usize, i: usize) {
        if bad.is_empty() || bad[i + 2 * m] == bad[i] {
            let d = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
            self.sum += d * d;
            self.terms += 1;
        } else {
            self.skipped += 1;
        }
    }
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

/// Factors summed side by side in one pass.
const LANES: usize = 8;

/// [`Terms`] of phase `x` at each factor of `factors` (each with x.len() > 2m), over
/// i = 0 … x.len() − 2m − 1.
///
/// Why in lanes: one factor's sum is a chain of dependent additions, so a loop per factor waits on
/// the adder's latency at every term; [`LANES`] factors in one pass keep that many independent
/// chains in flight. Each sum still adds its terms in index order, one at a time: every result is
/// the same number, bit for bit, as the plain loop per factor. A record without invalid samples
/// (`bad` all zero, the usual case) takes a loop without the validity test.
fn second_difference_sums(x: &[f64], bad: &[usize], factors: &[usize]) -> Vec<Terms> {
    let gap_free = bad.last().is_none_or(|&b| b == 0);
    let mut out = Vec::with_capacity(factors.len());
    for group in factors.chunks(LANES) {
        // A short last group repeats its last factor: the spare lanes cost no latency.
        let ms: [usize; LANES] = std::array::from_fn(|k| group[k.min(group.len() - 1)]);
        let acc = if gap_free {
            lanes::<false>(x, bad, ms)
        } else {
            lanes::<true>(x, bad, ms)
        };
        out.extend_from_slice(&acc[..group.len()]);
    }
    out
}

/// [`Terms`] of [`LANES`] factors in one pass; `CHECK`: test each term's samples for validity
/// (without it, for a record with no invalid sample, every term counts).
///
/// A lane's terms end at x.len() − 2m, so the pass runs in segments between those ends; in a
/// segment, a lane that has ended repeats an active lane's factor and its sum is restored after
/// (spare work, but no lane ever runs alone and waits on the adder's latency).
fn lanes<const CHECK: bool>(x: &[f64], bad: &[usize], ms: [usize; LANES]) -> [Terms; LANES] {
    let mut acc = [Terms::default(); LANES];
    let ends = ms.map(|m| x.len() - 2 * m);
    let mut from = 0;
    while let Some(to) = ends.iter().copied().filter(|&e| e > from).min() {
        let spare = ms[ends.iter().position(|&e| e > from).expect("an active lane")];
        let run = std::array::from_fn(|k| if ends[k] > from { ms[k] } else { spare });
        let kept = acc;
        segment::<CHECK>(x, bad, run, from..to, &mut acc);
        for k in (0..LANES).filter(|&k| ends[k] <= from) {
            acc[k] = kept[k];
        }
        from = to;
    }
    acc
}

/// Indices per block of [`segment`].
const BLOCK: usize = 256;

/// Adds the terms i ∈ `range` of each lane's factor to `acc`, in index order.
///
/// In blocks of [`BLOCK`] indices cut as fixed-size arrays: inside a block no index needs a bounds
/// check, and the lanes' sums stay in registers.
fn segment<const CHECK: bool>(
    x: &[f64],
    bad: &[usize],
    ms: [usize; LANES],
    range: std::ops::Range<usize>,
    acc: &mut [Terms; LANES],
) {
    fn block<T>(v: &[T], from: usize) -> &[T; BLOCK] {
        v[from..from + BLOCK].try_into().expect("BLOCK values")
    }
    let mut i = range.start;
    while i + BLOCK <= range.end {
        let x0 = block(x, i);
        let x1 = ms.map(|m| block(x, i + m));
        let x2 = ms.map(|m| block(x, i + 2 * m));
        // Without CHECK every term is valid and `bad` may be empty: nothing of it is read.
        let (b0, b2) = if CHECK {
            (block(bad, i), ms.map(|m| block(bad, i + 2 * m)))
        } else {
            (&[0; BLOCK], [&[0; BLOCK]; LANES])
        };
        for j in 0..BLOCK {
            for (k, t) in acc.iter_mut().enumerate() {
                if !CHECK || b2[k][j] == b0[j] {
                    let d = x2[k][j] - 2.0 * x1[k][j] + x0[j];
                    t.sum += d * d;
                    t.terms += 1;
                } else {
                    t.skipped += 1;
                }
            }
        }
        i += BLOCK;
    }
    for i in i..range.end {
        for (t, &m) in acc.iter_mut().zip(&ms) {
            t.add(x, if CHECK { bad } else { &[] }, m, i);
        }
    }
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

        // The lanes, segments and blocks give every factor's sum bit for bit as the plain loop
        // over i for that factor alone (with and without invalid samples).
        #[test]
        fn lanes_equal_the_plain_loop_exactly(y in prop::collection::vec(-10f64..10.0, 600..1400), holes in prop::collection::vec(0usize..1400, 0..3), pick in prop::collection::vec(1usize..300, 1..20)) {
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
            // Without invalid samples `bad` may be left empty: the same sums.
            let gap_free = bad.last() == Some(&0);
            let got_empty = gap_free.then(|| second_difference_sums(&x, &[], &factors));
            prop_assert!(got_empty.is_none_or(|e| e.iter().zip(&got).all(|(a, b)| a.sum.to_bits() == b.sum.to_bits() && a.terms == b.terms)));
            for (t, &m) in got.iter().zip(&factors) {
                let mut want = Terms::default();
                for i in 0..x.len() - 2 * m {
                    want.add(&x, &bad, m, i);
                }
                prop_assert_eq!(t.sum.to_bits(), want.sum.to_bits(), "m = {}", m);
                prop_assert_eq!((t.terms, t.skipped), (want.terms, want.skipped));
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

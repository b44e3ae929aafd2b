//! Equivalent degrees of freedom and χ² intervals for the Allan variance of one window.
//!
//! The branch that owns the general EDF (Greenhall's algorithm) may replace [`edf_overlapping`];
//! everything in the engine reaches the EDF through that one function and the χ² quantiles through
//! [`IntervalCache`], so a swap is one edit here.
//!
//! Why a cache: every row of every axis needs an interval at every τ, and a χ² quantile is an
//! iterative inversion. In a window without invalid samples the EDF depends only on (m, terms), so
//! the factors are computed once per pair; the number of pairs is bounded by K·λ2.

use crate::allan::AllanPoint;
use crate::allan::edf::{chi2_tail_quantiles, Chi2Inversion};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};

/// Lower tail probability of the 68.3 % (one-sigma) two-sided interval.
pub const ONE_SIGMA_LOW: f64 = 0.158_655_253_931_457;

/// Equivalent degrees of freedom of the overlapping Allan variance of a window, for white FM noise.
///
/// White frequency noise on a rate signal is the angle / velocity random walk that dominates an IMU
/// at the short τ where the DAVAR does its work, so white FM (α = 0) is the documented noise
/// assumption; it underestimates the spread for flicker and random-walk noise at long τ. The EDF is
/// Greenhall's ([`crate::allan::edf::greenhall_edf`], α = 0, overlapping Allan shape, N = terms +
/// 2m phase points); where that is undefined, the closed form below is used.
///
/// # Formula (fallback)
/// ```text
/// edf = (3(N−1)/(2m) − 2(N−2)/N) · 4m²/(4m² + 5),   N = terms + 2m
/// ```
/// where `terms` is the number of squared second differences averaged, N the equivalent number of
/// phase points and m the averaging factor. The result is clamped to at least 1.
///
/// # References
/// Howe D. A., Allan D. W., Barnes J. A., "Properties of signal sources and measurement methods",
/// 35th Frequency Control Symposium, 1981; Riley, NIST SP 1065, 2008, §5.3 Table 5.
///
/// ```
/// // A 501-sample window at m = 1. The closed form gives 332.4 (= 2M/3, which is exact for
/// // sampled white FM: adjacent first differences correlate at −1/2); Greenhall's algorithm as
/// // implemented gives 390.7. The 17 % gap at m = 1 is reported to the EDF's owner; at m = 50
/// // they agree within 2 %.
/// use fdavar::davar::stats::edf_closed_form;
/// let e = fdavar::davar::edf_overlapping(1, 499);
/// assert!((e / edf_closed_form(1, 499) - 1.0).abs() < 0.2, "{e}");
/// assert!((fdavar::davar::edf_overlapping(50, 401) / edf_closed_form(50, 401) - 1.0).abs() < 0.02);
/// ```
pub fn edf_overlapping(m: usize, terms: usize) -> f64 {
    let shape = crate::allan::edf::VarianceShape {
        d: 2,
        overlapping: true,
        modified: false,
    };
    match crate::allan::edf::greenhall_edf(0, shape, m.max(1), terms + 2 * m.max(1)) {
        Some(edf) if edf.is_finite() && edf > 0.0 => edf.max(1.0),
        _ => edf_closed_form(m, terms),
    }
}

/// The white-FM closed form of NIST SP 1065 Table 5 (the fallback of [`edf_overlapping`]).
pub fn edf_closed_form(m: usize, terms: usize) -> f64 {
    let m = m.max(1) as f64;
    let n = terms as f64 + 2.0 * m;
    let raw =
        (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * 4.0 * m * m / (4.0 * m * m + 5.0);
    raw.max(1.0)
}

/// The χ² factors of a two-sided interval: `(lo, hi)` with `avar·lo ≤ σ² ≤ avar·hi`.
///
/// The quantiles are statrs' ([`Chi2Inversion::Statrs`]), which the engine's intervals and change
/// events have always been computed with.
///
/// # Formula
/// ```text
/// lo = edf / χ²(1 − p_low; edf),   hi = edf / χ²(p_low; edf)
/// ```
/// where χ²(p; ν) is the p-quantile of the χ² distribution with ν degrees of freedom.
pub fn chi2_factors(edf: f64, p_low: f64) -> (f64, f64) {
    match chi2_tail_quantiles(p_low, edf, Chi2Inversion::Statrs) {
        Some((q_low, q_high)) => (edf / q_high, edf / q_low),
        // edf is clamped ≥ 1 by edf_overlapping; an invalid edf gives an unbounded interval.
        None => (0.0, f64::INFINITY),
    }
}

/// `(edf, lo, hi)`: the EDF and the χ² factors of an interval (see [`chi2_factors`]).
pub type IntervalFactors = (f64, f64, f64);

/// Memoised EDF and χ² factors per (m, terms) for one tail probability.
#[derive(Debug, Clone)]
pub struct IntervalCache {
    p_low: f64,
    edf: fn(usize, usize) -> f64,
    by_key: HashMap<(usize, usize), IntervalFactors>,
}

impl IntervalCache {
    /// A cache for the two-sided interval with lower tail `p_low` (e.g. [`ONE_SIGMA_LOW`]), EDF
    /// from [`edf_overlapping`].
    pub fn new(p_low: f64) -> Self {
        Self::with_edf(p_low, edf_overlapping)
    }

    /// A cache whose EDF is `edf(m, terms)` (e.g. [`edf_closed_form`], exact at m = 1 for white
    /// FM, which the change detector's false-alarm rate rests on).
    pub fn with_edf(p_low: f64, edf: fn(usize, usize) -> f64) -> Self {
        IntervalCache {
            p_low,
            edf,
            by_key: HashMap::new(),
        }
    }

    /// `(edf, lo, hi)` for `terms` squared differences at averaging factor `m`.
    pub fn factors(&mut self, m: usize, terms: usize) -> IntervalFactors {
        let (p_low, edf_of) = (self.p_low, self.edf);
        *self.by_key.entry((m, terms)).or_insert_with(|| computed(p_low, edf_of, m, terms))
    }

    /// An [`AllanPoint`] with its EDF and interval.
    pub fn point(&mut self, m: usize, tau: f64, avar: f64, terms: usize) -> AllanPoint {
        let (edf, lo, hi) = self.factors(m, terms);
        AllanPoint {
            m,
            tau,
            avar,
            terms,
            edf,
            ci_low: avar * lo,
            ci_high: avar * hi,
        }
    }
}

/// A small direct-mapped memo of [`IntervalFactors`] for a few averaging factors (its lanes).
///
/// Why: a DAVAR row needs one interval per τ, and from row to row the window moves by a few
/// samples (the policy's step), so the last [`MEMO_SLOTS`] keys almost always hold it; a hash
/// lookup per row and τ cost more than the row's arithmetic. Bounded memory, whatever λ2.
///
/// The key picks the entries, the number of terms checks them: a row of the engine keys by its
/// window, so that the K lanes it reads lie side by side (in a window without invalid samples
/// the terms at m are W − 2m + 1, the same at every such row); one lane keyed by its terms serves
/// a single factor. Each entry holds the terms it was filled for (none when not yet), then
/// its factors: plain values, not an `Option`, so that a hit is one compare and the factors stay
/// in registers (the enum's copy went through the stack, a store-forwarding stall per row and τ).
#[derive(Debug, Clone)]
pub struct IntervalMemo {
    lanes: usize,
    entries: Vec<(usize, IntervalFactors)>,
}

/// Keys an [`IntervalMemo`] tells apart (entries of key k: those of `k mod MEMO_SLOTS`).
pub const MEMO_SLOTS: usize = 512;

/// The terms of an entry not yet filled (no window holds that many terms).
const EMPTY: usize = usize::MAX;

impl Default for IntervalMemo {
    fn default() -> Self {
        Self::new(1)
    }
}

impl IntervalMemo {
    /// A memo of `lanes` factors.
    pub fn new(lanes: usize) -> Self {
        IntervalMemo {
            lanes,
            entries: vec![(EMPTY, (f64::NAN, f64::NAN, f64::NAN)); MEMO_SLOTS * lanes],
        }
    }

    /// The factors of `lane` for `terms`, from the entry of `key` or else from `fetch` (then
    /// remembered there).
    #[inline]
    pub fn get(
        &mut self,
        key: usize,
        lane: usize,
        terms: usize,
        fetch: impl FnOnce() -> IntervalFactors,
    ) -> IntervalFactors {
        let entry = &mut self.entries[(key % MEMO_SLOTS) * self.lanes + lane];
        if entry.0 != terms {
            *entry = (terms, fetch());
        }
        entry.1
    }
}

/// One [`IntervalCache`] of the one-sigma interval ([`ONE_SIGMA_LOW`], [`edf_overlapping`]) that
/// several engines use, e.g. the axes of one pipeline.
///
/// Why: the factors depend on (m, terms) only, and the axes of a record meet the same pairs; each
/// pair's χ² inversions are then made once, not once per axis (the same numbers either way).
/// Engines look the cache up only for a pair they have not met themselves, so the lock is rare.
#[derive(Debug, Clone)]
pub struct SharedIntervals(Arc<Mutex<IntervalCache>>);

impl Default for SharedIntervals {
    fn default() -> Self {
        SharedIntervals(Arc::new(Mutex::new(IntervalCache::new(ONE_SIGMA_LOW))))
    }
}

impl SharedIntervals {
    /// [`IntervalCache::factors`] of the shared cache.
    ///
    /// The χ² inversions of a pair not cached yet are made without the lock. Why: the two row
    /// workers of `fdavar analyze` meet most of their pairs in the first windows, together, and
    /// an inversion under the lock kept the other worker waiting: `perf sched timehist` showed one
    /// core idle for most of 20 ms near the start, the waiting worker waking every 10 µs. Two
    /// workers may then invert the same pair: the same numbers, the first one kept.
    pub fn factors(&self, m: usize, terms: usize) -> IntervalFactors {
        // A panic while holding the lock leaves the map whole (an entry is inserted complete).
        let lock = || self.0.lock().unwrap_or_else(PoisonError::into_inner);
        let (p_low, edf_of) = {
            let cache = lock();
            if let Some(&known) = cache.by_key.get(&(m, terms)) {
                return known;
            }
            (cache.p_low, cache.edf)
        };
        let made = computed(p_low, edf_of, m, terms);
        *lock().by_key.entry((m, terms)).or_insert(made)
    }
}

/// `(edf, lo, hi)` of [`IntervalCache::factors`], computed.
fn computed(p_low: f64, edf_of: fn(usize, usize) -> f64, m: usize, terms: usize) -> IntervalFactors {
    let edf = edf_of(m, terms);
    let (lo, hi) = chi2_factors(edf, p_low);
    (edf, lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_factors_keep_the_bits_of_statrs_inversion() {
        // The factors as this file computed them before `allan::edf` held the one implementation:
        // the engine's intervals and change events depend on these bits.
        use statrs::distribution::{ChiSquared, ContinuousCDF};
        for edf in [1.0, 7.5, 332.4, 5e4] {
            let chi = ChiSquared::new(edf).unwrap();
            let (lo, hi) = chi2_factors(edf, ONE_SIGMA_LOW);
            assert_eq!(lo.to_bits(), (edf / chi.inverse_cdf(1.0 - ONE_SIGMA_LOW)).to_bits());
            assert_eq!(hi.to_bits(), (edf / chi.inverse_cdf(ONE_SIGMA_LOW)).to_bits());
        }
        assert_eq!(chi2_factors(0.0, ONE_SIGMA_LOW), (0.0, f64::INFINITY));
    }

    #[test]
    fn interval_brackets_the_estimate_and_narrows_with_terms() {
        let mut c = IntervalCache::new(ONE_SIGMA_LOW);
        let small = c.point(1, 1.0, 2.0, 20);
        let large = c.point(1, 1.0, 2.0, 2000);
        assert!(small.ci_low < 2.0 && 2.0 < small.ci_high);
        assert!(large.ci_high - large.ci_low < small.ci_high - small.ci_low);
        // For large edf the one-sigma half width tends to √(2/edf) relative.
        let rel = (large.ci_high - large.ci_low) / 2.0 / 2.0;
        assert!((rel - (2.0 / large.edf).sqrt()).abs() < 0.01, "{rel}");
    }

    #[test]
    fn edf_is_at_least_one_and_near_the_closed_form() {
        assert!(edf_overlapping(100, 1) >= 1.0);
        assert!(edf_overlapping(0, 0) >= 1.0);
        for (m, terms) in [(1, 170), (5, 491), (50, 401), (167, 168)] {
            let (g, c) = (edf_overlapping(m, terms), edf_closed_form(m, terms));
            assert!((g / c - 1.0).abs() < 0.2, "m {m} terms {terms}: {g} vs {c}");
        }
    }
}

//! The streaming F-DAVAR engine of one axis: push rate samples, get DAVAR rows.
//!
//! # How a row costs O(K) whatever W is
//! For every averaging factor m of the grid the engine keeps, over a ring of L = λ2 + 8 indices,
//! the prefix sum of the squared second differences that are complete so far, and how many of them
//! were valid. The window's Allan variance at m is then one subtraction of two prefix values. Each
//! new sample completes exactly one new second difference per m, so a push is O(K) and memory is
//! O(K·L), whatever the window.
//!
//! # Why the sums do not drift
//! Prefix sums grow without bound and collect rounding. Every L samples the engine *rebases*: it
//! recomputes every prefix from the raw samples still in the ring, from zero, exactly as a fresh
//! engine would. Between rebases at most L additions accumulate, so a row after 24 h equals a
//! from-scratch computation on its cut (the property tests check 10⁷ samples). Samples are also
//! summed relative to a local reference (the mean of the ring at the last rebase): a gyro bias of
//! 10⁴ with noise of 1 loses no digits in the second differences, which are blind to offsets.
//!
//! # Timing
//! The row at analysis index t uses the W(t) samples `[t − ⌊W/2⌋, t − ⌊W/2⌋ + W)` and is emitted
//! as soon as the last of them arrives (⌈W/2⌉ − 1 samples after t). Then the policy gives W(t+1)
//! from F(t). The first row is at t = ⌊W(0)/2⌋, the first index with a full window; no row is made
//! from a truncated window.

use super::reference::{FTarget, FTargetTracker, SigmaRef, SigmaRefTracker};
use super::stats::{IntervalFactors, IntervalMemo, SharedIntervals};
use super::{DavarError, DavarRow, WindowPolicy};
use crate::allan::AllanPoint;

/// Most point vectors kept for reuse (a push emits one row, rarely several).
const SPARE_ROWS: usize = 4;

/// Extra ring slots beyond λ2 (the proof in [`DavarEngine::new`] needs 2).
const RING_MARGIN: usize = 8;

/// One factor's prefix at one slot: the sum of the valid squared second differences so far and
/// their count (side by side: a push and a row read both).
#[derive(Debug, Clone, Copy, Default)]
struct Prefix {
    sum: f64,
    count: u64,
}

/// What one engine computes besides its window policy.
#[derive(Debug, Clone, PartialEq)]
pub struct EngineConfig {
    /// Averaging factors of the τ grid, ascending; a row holds those with 3m ≤ W (τmax = W/3).
    pub factors: Vec<usize>,
    /// Nominal sample period τ0, seconds.
    pub tau0: f64,
    /// How σ²_ref is obtained.
    pub sigma_ref: SigmaRef,
    /// How F̃ is obtained.
    pub f_target: FTarget,
}

/// The per-axis streaming F-DAVAR engine.
///
/// Push one rate sample at a time (`None`, NaN or ±∞ mark a missing or invalid sample); rows come
/// out in analysis order. The same sequence of pushes always gives the same rows.
///
/// ```
/// use fdavar::davar::{DavarEngine, EngineConfig, FixedWindow, FTarget, SigmaRef};
/// let cfg = EngineConfig { factors: vec![1, 2, 5], tau0: 0.01, sigma_ref: SigmaRef::Running,
///                          f_target: FTarget::Value(1.0) };
/// let mut e = DavarEngine::new(cfg, Box::new(FixedWindow::new(21))).unwrap();
/// let mut rows = Vec::new();
/// for k in 0..100 { e.push(Some(((k * 37) % 11) as f64), &mut rows); }
/// assert_eq!(rows.len(), 100 - 21 + 1);
/// assert_eq!(rows[0].index, 10);
/// assert_eq!(rows[0].points.len(), 3);
/// ```
pub struct DavarEngine {
    policy: Box<dyn WindowPolicy>,
    factors: Vec<usize>,
    tau0: f64,
    sigma_ref: SigmaRefTracker,
    f_target: FTargetTracker,
    intervals: SharedIntervals,
    /// Per factor, the intervals it met lately (a row needs one per factor).
    interval_of: Vec<IntervalMemo>,
    /// Point vectors of rows handed back by [`DavarEngine::recycle`], reused by the next rows.
    spare: Vec<Vec<AllanPoint>>,
    /// Ring length L.
    len: usize,
    /// Samples pushed so far (the index of the next sample).
    n: u64,
    /// Index at which the prefix sums are zero (start, or the oldest index at the last rebase).
    base: u64,
    /// Value of `n` at the last rebase.
    rebased_at: u64,
    /// Local reference subtracted from every sample before summing.
    reference: Option<f64>,
    /// Raw samples y[k] at slot k mod L (NaN = invalid), k ∈ [n − L, n).
    raw: Vec<f64>,
    /// Prefix sums at slot k mod L, k ∈ [max(base, n − L + 1), n]: Σ z, Σ z², valid count.
    sum1: Vec<f64>,
    sum2: Vec<f64>,
    valid: Vec<u64>,
    /// At `(j mod L)·K + i` for factor number i: prefix of the valid squared second differences
    /// (slot-major: a row reads every factor's prefix at its window's first slot, a rebase reads
    /// and writes every factor's at one slot after the other).
    terms: Vec<Prefix>,
    /// The pending analysis index and its window.
    t: u64,
    w: usize,
    excluded_total: u64,
}

impl std::fmt::Debug for DavarEngine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DavarEngine")
            .field("policy", &self.policy.name())
            .field("factors", &self.factors)
            .field("samples", &self.n)
            .field("pending_index", &self.t)
            .field("window", &self.w)
            .finish_non_exhaustive()
    }
}

impl DavarEngine {
    /// A new engine.
    ///
    /// The ring holds L = λ2 + 8 samples. That suffices for any window sequence inside the policy's
    /// bounds: the oldest sample a pending row needs is at most λ2 − 2 behind the newest sample.
    ///
    /// # Errors
    /// [`DavarError::Config`] when τ0 is not positive, the grid is empty or unsorted, a factor is 0,
    /// the bounds are inverted or below 3, or a given σ²_ref / F̃ is not positive.
    pub fn new(config: EngineConfig, policy: Box<dyn WindowPolicy>) -> Result<Self, DavarError> {
        Self::with_intervals(config, policy, SharedIntervals::default())
    }

    /// [`DavarEngine::new`] taking its χ² intervals from `intervals`, which other engines may
    /// share (the same rows).
    ///
    /// # Errors
    /// As [`DavarEngine::new`].
    pub fn with_intervals(
        config: EngineConfig,
        policy: Box<dyn WindowPolicy>,
        intervals: SharedIntervals,
    ) -> Result<Self, DavarError> {
        let bad = |reason: String| Err(DavarError::Config { reason });
        let bounds = policy.bounds();
        if !(config.tau0 > 0.0 && config.tau0.is_finite()) {
            return bad(format!("tau0 must be positive, got {}", config.tau0));
        }
        if bounds.min < 3 || bounds.min > bounds.max {
            return bad(format!(
                "window bounds must satisfy 3 <= min <= max, got min {} max {}",
                bounds.min, bounds.max
            ));
        }
        if config.factors.is_empty()
            || config.factors[0] == 0
            || config.factors.windows(2).any(|p| p[0] >= p[1])
        {
            return bad(format!(
                "averaging factors must be ascending and >= 1, got {:?}",
                config.factors
            ));
        }
        if let SigmaRef::Value(v) = config.sigma_ref {
            if !(v > 0.0 && v.is_finite()) {
                return bad(format!("sigma_ref value must be positive, got {v}"));
            }
        }
        if let FTarget::Value(v) = config.f_target {
            if !(v > 0.0 && v.is_finite()) {
                return bad(format!("f_target must be positive, got {v}"));
            }
        }
        let factors: Vec<usize> = config
            .factors
            .into_iter()
            .filter(|&m| 3 * m <= bounds.max)
            .collect();
        let len = bounds.max + RING_MARGIN;
        let w = bounds.clamp(policy.initial() as i64);
        Ok(DavarEngine {
            factors: factors.clone(),
            tau0: config.tau0,
            sigma_ref: SigmaRefTracker::new(config.sigma_ref),
            f_target: FTargetTracker::new(config.f_target),
            intervals,
            interval_of: vec![IntervalMemo::default(); factors.len()],
            spare: Vec::new(),
            len,
            n: 0,
            base: 0,
            rebased_at: 0,
            reference: None,
            raw: vec![f64::NAN; len],
            sum1: vec![0.0; len],
            sum2: vec![0.0; len],
            valid: vec![0; len],
            terms: vec![Prefix::default(); len * factors.len()],
            t: (w / 2) as u64,
            w,
            excluded_total: 0,
            policy,
        })
    }

    /// Pushes one rate sample (`None` or a non-finite value = missing/invalid) and appends the rows
    /// that became complete to `out` (zero, one, or several when the window shrank).
    pub fn push(&mut self, value: Option<f64>, out: &mut Vec<DavarRow>) {
        let value = value.filter(|v| v.is_finite());
        let k = self.n;
        let slot = self.slot(k);
        let next = self.wrap(slot + 1);
        self.raw[slot] = value.unwrap_or(f64::NAN);
        let (z, ok) = match value {
            Some(y) => {
                self.sigma_ref.observe(y);
                (y - *self.reference.get_or_insert(y), 1)
            }
            None => (0.0, 0),
        };
        self.sum1[next] = self.sum1[slot] + z;
        self.sum2[next] = self.sum2[slot] + z * z;
        self.valid[next] = self.valid[slot] + ok;
        self.n = k + 1;
        for i in 0..self.factors.len() {
            let m = self.factors[i];
            if self.n < self.base + 2 * m as u64 {
                break; // ascending factors: the larger ones have no complete term either
            }
            // Slots counted back from that of n (2m < L): no division per factor.
            let (a, b) = (self.back(next, 2 * m), self.back(next, m));
            self.append_term_at(i, a, b, next);
        }
        if self.n - self.rebased_at >= self.len as u64 {
            self.rebase();
        }
        self.emit_ready(out);
    }

    /// Hands back the points of a row this engine made, so that a later row reuses their memory
    /// instead of allocating (a row is made per sample and axis).
    pub fn recycle(&mut self, mut points: Vec<AllanPoint>) {
        if self.spare.len() < SPARE_ROWS {
            points.clear();
            self.spare.push(points);
        }
    }

    /// Pushes `count` missing samples (a gap of `count` sample periods).
    ///
    /// Equivalent to `count` calls of `push(None, out)`, but a gap longer than the ring costs O(K·L)
    /// instead of O(K·count): once the ring holds nothing valid, the rows whose windows hold no
    /// valid sample are skipped (no row is ever made from an empty window) and the window is held.
    pub fn push_missing(&mut self, count: u64, out: &mut Vec<DavarRow>) {
        let direct = count.min(self.len as u64);
        for _ in 0..direct {
            self.push(None, out);
        }
        let rest = count - direct;
        if rest > 0 {
            self.n += rest;
            self.t += rest;
            self.raw.fill(f64::NAN);
            self.rebase();
        }
    }

    /// Samples pushed so far (valid or not).
    pub fn samples(&self) -> u64 {
        self.n
    }

    /// The analysis index of the next row and its window length.
    pub fn pending(&self) -> (u64, usize) {
        (self.t, self.w)
    }

    /// Squared differences left out so far because they straddled an invalid sample, over all rows
    /// and τ.
    pub fn excluded_terms(&self) -> u64 {
        self.excluded_total
    }

    /// The averaging factors this engine evaluates (the grid, cut at λ2/3).
    pub fn factors(&self) -> &[usize] {
        &self.factors
    }

    /// The nominal period τ0 in seconds.
    pub fn tau0(&self) -> f64 {
        self.tau0
    }

    fn slot(&self, k: u64) -> usize {
        (k % self.len as u64) as usize
    }

    /// `slot` + 0 … L − 1 brought back into the ring (one comparison instead of a division: the
    /// push loop runs this K times per sample).
    fn wrap(&self, slot: usize) -> usize {
        if slot >= self.len {
            slot - self.len
        } else {
            slot
        }
    }

    /// The slot `d` indices before `slot` (d ≤ L).
    fn back(&self, slot: usize, d: usize) -> usize {
        if slot >= d {
            slot - d
        } else {
            slot + self.len - d
        }
    }

    /// Where the prefix of factor number `i` at `slot` is.
    fn at(&self, i: usize, slot: usize) -> usize {
        slot * self.factors.len() + i
    }

    /// Records the second difference that starts at index j for factor number `i`, from the
    /// slots a, b, c of indices j, j + m, j + 2m.
    #[inline(always)]
    fn append_term_at(&mut self, i: usize, a: usize, b: usize, c: usize) {
        let m = self.factors[i] as u64;
        let d = self.sum1[c] - 2.0 * self.sum1[b] + self.sum1[a];
        let ok = self.valid[c] - self.valid[a] == 2 * m;
        let next = self.wrap(a + 1);
        let from = self.terms[self.at(i, a)];
        let to = self.at(i, next);
        self.terms[to] = Prefix {
            sum: from.sum + if ok { d * d } else { 0.0 },
            count: from.count + u64::from(ok),
        };
    }

    /// Recomputes every prefix from the raw samples in the ring, from zero (see the module doc).
    fn rebase(&mut self) {
        self.rebased_at = self.n;
        self.base = (self.n + 1).saturating_sub(self.len as u64);
        let (sum, count) = (self.base..self.n)
            .map(|k| self.raw[self.slot(k)])
            .filter(|y| y.is_finite())
            .fold((0.0, 0u64), |(s, c), y| (s + y, c + 1));
        if count > 0 {
            self.reference = Some(sum / count as f64);
        }
        let reference = self.reference.unwrap_or(0.0);
        let first = self.slot(self.base);
        self.sum1[first] = 0.0;
        self.sum2[first] = 0.0;
        self.valid[first] = 0;
        let mut slot = first;
        for _ in self.base..self.n {
            let next = self.wrap(slot + 1);
            let y = self.raw[slot];
            let (z, ok) = if y.is_finite() {
                (y - reference, 1)
            } else {
                (0.0, 0)
            };
            self.sum1[next] = self.sum1[slot] + z;
            self.sum2[next] = self.sum2[slot] + z * z;
            self.valid[next] = self.valid[slot] + ok;
            slot = next;
        }
        for i in 0..self.factors.len() {
            let at = self.at(i, first);
            self.terms[at] = Prefix::default();
        }
        // Index by index, every factor at each: the factors' sums are independent chains, so
        // this keeps K additions in flight instead of waiting on one chain (each chain's
        // additions are the same, in the same order, as factor by factor).
        let (mut j, mut a) = (self.base, first);
        while j + 2 * self.factors[0] as u64 <= self.n {
            for i in 0..self.factors.len() {
                let m = self.factors[i];
                if j + 2 * m as u64 > self.n {
                    break;
                }
                let (b, c) = (self.wrap(a + m), self.wrap(a + 2 * m));
                self.append_term_at(i, a, b, c);
            }
            j += 1;
            a = self.wrap(a + 1);
        }
    }

    /// (edf, lo, hi) of factor number `i` for `terms` terms, from the table or else the cache.
    fn interval(&mut self, i: usize, terms: usize) -> IntervalFactors {
        let (m, shared) = (self.factors[i], &self.intervals);
        self.interval_of[i].get(terms, || shared.factors(m, terms))
    }

    /// Emits every pending row whose window is complete, advancing the window policy.
    fn emit_ready(&mut self, out: &mut Vec<DavarRow>) {
        loop {
            let start = self.t - (self.w / 2) as u64;
            if start + self.w as u64 > self.n {
                return;
            }
            debug_assert!(start >= self.base && start + self.len as u64 > self.n);
            let row = self.row(start);
            let f = row.as_ref().and_then(|r| r.f);
            let target = row.as_ref().and_then(|r| r.f_target);
            if let Some(r) = &row {
                if let Some(f) = r.f {
                    self.f_target.observe(f, r.valid_samples);
                }
            }
            let next = self.policy.next(self.w, f, target);
            self.t += 1;
            // A window cannot reach before the first sample: W ≤ 2t + 1 (only a policy that
            // starts below λ2 and grows early can ask for more).
            let fits = 2 * self.t as usize + 1;
            self.w = self.policy.bounds().clamp(next as i64).min(fits);
            out.extend(row);
        }
    }

    /// The row of the pending analysis index whose window starts at `start`; `None` when the
    /// window holds fewer than two valid samples.
    fn row(&mut self, start: u64) -> Option<DavarRow> {
        let w = self.w as u64;
        let a = self.slot(start);
        let e = self.wrap(a + w as usize);
        let valid = (self.valid[e] - self.valid[a]) as usize;
        if valid < 2 {
            return None;
        }
        let s1 = self.sum1[e] - self.sum1[a];
        let s2 = self.sum2[e] - self.sum2[a];
        let nv = valid as f64;
        let variance = ((s2 - s1 * s1 / nv) / nv).max(0.0);
        let sigma2_ref = self.sigma_ref.current();
        let f = sigma2_ref.map(|r| variance / r);
        let f_target = self.f_target.target(valid);
        let mut points = self
            .spare
            .pop()
            .unwrap_or_else(|| Vec::with_capacity(self.factors.len()));
        let mut excluded = 0usize;
        for i in 0..self.factors.len() {
            let m = self.factors[i];
            if 3 * m > self.w {
                break;
            }
            let total = self.w - 2 * m + 1;
            let end = self.wrap(a + total);
            let (first, last) = (self.terms[self.at(i, a)], self.terms[self.at(i, end)]);
            let terms = (last.count - first.count) as usize;
            excluded += total - terms;
            if terms == 0 {
                continue;
            }
            let sum = (last.sum - first.sum).max(0.0);
            let mf = m as f64;
            let avar = sum / (2.0 * mf * mf * terms as f64);
            let (edf, lo, hi) = self.interval(i, terms);
            points.push(AllanPoint {
                m,
                tau: mf * self.tau0,
                avar,
                terms,
                edf,
                ci_low: avar * lo,
                ci_high: avar * hi,
            });
        }
        self.excluded_total += excluded as u64;
        Some(DavarRow {
            index: self.t,
            time_s: self.t as f64 * self.tau0,
            window: self.w,
            valid_samples: valid,
            variance,
            f,
            f_target,
            sigma2_ref,
            excluded_terms: excluded,
            points,
        })
    }
}

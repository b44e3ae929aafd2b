//! The streaming F-DAVAR engine of one axis: push rate samples, get DAVAR rows.
//!
//! # How a row costs O(K) whatever W is
//! For every averaging factor m of the grid the engine keeps the prefix sum of the squared second
//! differences that are complete so far, and how many of them were valid, over the last L = λ2 + 8
//! indices. The window's Allan variance at m is then one subtraction of two prefix values. Each
//! new sample completes exactly one new second difference per m, so a push is O(K) and memory is
//! O(K·L), whatever the window.
//!
//! # Why the sums do not drift
//! Prefix sums grow without bound and collect rounding. Every L samples the engine *rebases*: it
//! recomputes every prefix from the raw samples it still holds, from zero, exactly as a fresh
//! engine would. Between rebases at most L additions accumulate, so a row after 24 h equals a
//! from-scratch computation on its cut (the property tests check 10⁷ samples). Samples are also
//! summed relative to a local reference (the mean of the held samples at the last rebase): a gyro
//! bias of 10⁴ with noise of 1 loses no digits in the second differences, which are blind to
//! offsets.
//!
//! # Layout
//! The arrays are linear, 2L positions long: position p holds what belongs to index origin + p.
//! A rebase moves the L − 1 samples it keeps to the front (it rewrites every prefix anyway), and
//! the next L samples fill the rest. Why not a ring of L: every access then wraps its index
//! (a branch per factor and sample). Each factor's prefix is stored at the position of the
//! sample count that completed its latest term, not at that term's first index: a push then reads
//! and writes each factor's prefixes at two adjacent positions, and a row reads the K upper ends
//! of its window's sums at one position. Each sum adds the same terms in the same order either way.
//!
//! The prefixes are factor-major (one lane of 2L positions per factor) and their sums and counts
//! are separate arrays. Why: a row also reads each factor's lower end, at a position that depends
//! on m (up to W back). Position-major, those K reads hit K cache lines written about W samples
//! earlier, every row (a third of a push's time, measured with `perf annotate`); in lanes each
//! factor's lower end moves one position per row, so a cache line serves eight rows. A window
//! whose samples are all valid has every term valid: its counts are known without reading them.
//!
//! # Timing
//! The row at analysis index t uses the W(t) samples `[t − ⌊W/2⌋, t − ⌊W/2⌋ + W)` and is emitted
//! as soon as the last of them arrives (⌈W/2⌉ − 1 samples after t). Then the policy gives W(t+1)
//! from F(t). The first row is at t = ⌊W(0)/2⌋, the first index with a full window; no row is made
//! from a truncated window.

use super::reference::{FTarget, FTargetTracker, SigmaRef, SigmaRefTracker};
use super::stats::{IntervalMemo, SharedIntervals, MEMO_SLOTS};
use super::{DavarError, DavarRow, PointLayout, RowLayout, WindowPolicy};
use std::sync::Arc;

/// Most variance vectors kept for reuse (a push emits one row, rarely several).
const SPARE_ROWS: usize = 4;

/// Extra held indices beyond λ2 (the proof in [`DavarEngine::new`] needs 2).
const RING_MARGIN: usize = 8;

/// A factor's constants in a row's point: τ = m·τ0 and the divisor's 2m² (the same products as
/// computed per row, made once).
#[derive(Debug, Clone, Copy)]
struct Scale {
    tau: f64,
    two_m2: f64,
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
/// assert_eq!(rows[0].points().len(), 3);
/// ```
pub struct DavarEngine {
    policy: Box<dyn WindowPolicy>,
    factors: Vec<usize>,
    /// Per factor, its [`Scale`].
    scales: Vec<Scale>,
    tau0: f64,
    sigma_ref: SigmaRefTracker,
    f_target: FTargetTracker,
    intervals: SharedIntervals,
    /// The intervals met lately, one lane per factor, keyed by window (a row needs one per factor).
    interval_of: IntervalMemo,
    /// Variance vectors of rows handed back by [`DavarEngine::recycle`], reused by the next rows.
    spare: Vec<Vec<f64>>,
    /// The layout of the latest row handed back: the next row of the same window takes it over
    /// instead of cloning it from `layouts`.
    ///
    /// Why: each clone and each drop of an `Arc` is an atomic read-modify-write; with a row per
    /// sample and axis, the two were 2 % of `fdavar analyze`'s CPU (`perf annotate`), and a
    /// window's rows mostly follow each other.
    spare_layout: Option<Arc<RowLayout>>,
    /// The layout of the rows of a window without invalid samples, by window (slot W mod
    /// [`MEMO_SLOTS`]): such rows of one window share it.
    layouts: Vec<Arc<RowLayout>>,
    /// 1/(2m²·terms) of each point of the layout in the same slot: σ²(τ) = sum × this.
    inverse_divisors: Vec<Vec<f64>>,
    /// Indices held, L; the engine rebases every L samples.
    len: usize,
    /// Samples pushed so far (the index of the next sample).
    n: u64,
    /// Index at which the prefix sums are zero (start, or the oldest index at the last rebase).
    base: u64,
    /// Index held at position 0 of the arrays (= `base`).
    origin: u64,
    /// Value of `n` at the last rebase.
    rebased_at: u64,
    /// Local reference subtracted from every sample before summing.
    reference: Option<f64>,
    /// Raw samples y[k] at position k − origin (NaN = invalid), k ∈ [origin, n).
    raw: Vec<f64>,
    /// Prefix sums over [base, k) at position k − origin, k ∈ [base, n]: Σ z, Σ z², valid count.
    sum1: Vec<f64>,
    sum2: Vec<f64>,
    valid: Vec<u64>,
    /// At `i·2L + k − origin` for factor number i, k ∈ [base, n]: prefix of the valid squared
    /// second differences of the terms j ≥ base complete among the samples [base, k), i.e. with
    /// j + 2m ≤ k (factor-major: see the module doc), and how many terms it holds.
    term_sums: Vec<f64>,
    term_counts: Vec<u64>,
    /// Whether `term_counts` is kept. It is not while every sample since base is valid: a count is
    /// then the number of terms complete at its position, and the first invalid sample fills
    /// them in (a gap-free record never does).
    counts_held: bool,
    /// The pending analysis index and its window.
    t: u64,
    w: usize,
    excluded_total: u64,
    /// The factors whose term sums are kept and put into rows: all of them, or the first only
    /// ([`DavarEngine::shortest_tau_only`]). Every factor's valid-term count is kept either way.
    summed_factors: usize,
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

impl PointLayout {
    /// Point `i` (factor `m`) of a row of window `w` whose sum holds `terms` terms: its interval
    /// from `memo`, else from `shared`.
    fn of(
        i: usize,
        m: usize,
        scale: &Scale,
        terms: usize,
        w: usize,
        memo: &mut IntervalMemo,
        shared: &SharedIntervals,
    ) -> PointLayout {
        let (edf, low, high) = memo.get(w, i, terms, || shared.factors(m, terms));
        PointLayout { m, tau: scale.tau, terms, edf, low, high }
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
        let scales = factors
            .iter()
            .map(|&m| {
                let mf = m as f64;
                Scale { tau: mf * config.tau0, two_m2: 2.0 * mf * mf }
            })
            .collect();
        Ok(DavarEngine {
            factors: factors.clone(),
            scales,
            tau0: config.tau0,
            sigma_ref: SigmaRefTracker::new(config.sigma_ref),
            f_target: FTargetTracker::new(config.f_target),
            intervals,
            interval_of: IntervalMemo::new(factors.len()),
            spare: Vec::new(),
            spare_layout: None,
            layouts: (0..MEMO_SLOTS).map(|_| Arc::default()).collect(),
            inverse_divisors: vec![Vec::new(); MEMO_SLOTS],
            len,
            n: 0,
            base: 0,
            origin: 0,
            rebased_at: 0,
            reference: None,
            raw: vec![f64::NAN; 2 * len],
            sum1: vec![0.0; 2 * len],
            sum2: vec![0.0; 2 * len],
            valid: vec![0; 2 * len],
            term_sums: vec![0.0; 2 * len * factors.len()],
            term_counts: vec![0; 2 * len * factors.len()],
            counts_held: false,
            t: (w / 2) as u64,
            w,
            excluded_total: 0,
            summed_factors: factors.len(),
            policy,
        })
    }

    /// The same engine whose rows hold only their shortest τ: the point the change detector reads.
    ///
    /// Why: a caller that keeps of each row its window, F and that point (`fdavar analyze`
    /// without figures) would otherwise have every row's K variances computed and dropped, a
    /// sixth of its row workers' time (`perf record`), and every push would extend K prefix sums
    /// of which one is read (11 % of `fdavar analyze`'s CPU; instructions of the whole job
    /// 12.98 G → 10.74 G, cachegrind). Windows, F, the shortest point and the excluded-term count
    /// are those of the full rows, bit for bit.
    pub fn shortest_tau_only(mut self) -> Self {
        self.summed_factors = 1;
        self
    }

    /// Pushes one rate sample (`None` or a non-finite value = missing/invalid) and appends the rows
    /// that became complete to `out` (zero, one, or several when the window shrank).
    pub fn push(&mut self, value: Option<f64>, out: &mut Vec<DavarRow>) {
        let value = value.filter(|v| v.is_finite());
        let p = self.pos(self.n);
        self.raw[p] = value.unwrap_or(f64::NAN);
        let (z, ok) = match value {
            Some(y) => {
                self.sigma_ref.observe(y);
                (y - *self.reference.get_or_insert(y), 1)
            }
            None => {
                if !self.counts_held {
                    self.hold_counts(p);
                }
                (0.0, 0)
            }
        };
        self.sum1[p + 1] = self.sum1[p] + z;
        self.sum2[p + 1] = self.sum2[p] + z * z;
        self.valid[p + 1] = self.valid[p] + ok;
        self.n += 1;
        self.append_terms(p + 1);
        if self.n - self.rebased_at >= self.len as u64 {
            self.rebase();
        }
        self.emit_ready(out);
    }

    /// Hands back a row this engine made, so that a later row reuses its memory instead of
    /// allocating (a row is made per sample and axis).
    pub fn recycle(&mut self, row: DavarRow) {
        self.recycle_parts(row.avars, row.layout);
    }

    /// [`DavarEngine::recycle`] of a row's variance vector and layout (taken out of the row).
    pub(crate) fn recycle_parts(&mut self, mut avars: Vec<f64>, layout: Option<Arc<RowLayout>>) {
        if self.spare.len() < SPARE_ROWS && avars.capacity() > 0 {
            avars.clear();
            self.spare.push(avars);
        }
        if layout.is_some() {
            self.spare_layout = layout;
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
            // Nothing held is valid: the rebase keeps NaN from the front of the arrays.
            self.raw.fill(f64::NAN);
            self.origin = (self.n + 1).saturating_sub(self.len as u64);
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

    /// The position of index `k` in the arrays.
    fn pos(&self, k: u64) -> usize {
        (k - self.origin) as usize
    }

    /// Appends to every factor's prefix the term that the prefix sums at position `p` complete
    /// (for factor m the one that starts at index origin + p − 2m), or zero while none is.
    ///
    /// Why by position: a push and a rebase both advance all factors by one sample; the factors'
    /// sums are independent chains, so K additions are in flight, and each chain adds its terms
    /// in index order (the same numbers as one factor at a time).
    ///
    /// An engine of [`DavarEngine::shortest_tau_only`] sums the first factor's terms only (its rows
    /// read no other sum) but counts every factor's (a row's excluded terms are over all of them).
    fn append_terms(&mut self, p: usize) {
        let span = 2 * self.len;
        let complete = self.origin + p as u64 - self.base;
        let s1 = &self.sum1[..=p];
        let sums = &mut self.term_sums;
        if !self.counts_held {
            // Every sample since base is valid, so is every term (see `counts_held`).
            for (i, &m) in self.factors[..self.summed_factors].iter().enumerate() {
                let at = i * span + p;
                sums[at] = if complete < 2 * m as u64 {
                    0.0 // no term of m starts at or after base yet
                } else {
                    let d = s1[p] - 2.0 * s1[p - m] + s1[p - 2 * m];
                    sums[at - 1] + d * d
                };
            }
            return;
        }
        let (valid, counts) = (&self.valid[..=p], &mut self.term_counts);
        for (i, &m) in self.factors.iter().enumerate() {
            let at = i * span + p;
            if complete < 2 * m as u64 {
                (sums[at], counts[at]) = (0.0, 0);
                continue;
            }
            let ok = valid[p] - valid[p - 2 * m] == 2 * m as u64;
            counts[at] = counts[at - 1] + u64::from(ok);
            if i < self.summed_factors {
                let d = s1[p] - 2.0 * s1[p - m] + s1[p - 2 * m];
                sums[at] = sums[at - 1] + if ok { d * d } else { 0.0 };
            }
        }
    }

    /// Fills the term counts of the positions up to `p` (all of their samples valid: each count is
    /// the number of terms complete there) and keeps them from now on.
    fn hold_counts(&mut self, p: usize) {
        let span = 2 * self.len;
        for (&m, counts) in self.factors.iter().zip(self.term_counts.chunks_exact_mut(span)) {
            for (q, count) in counts[..=p].iter_mut().enumerate() {
                let complete = self.origin + q as u64 - self.base;
                *count = (complete + 1).saturating_sub(2 * m as u64);
            }
        }
        self.counts_held = true;
    }

    /// Recomputes every prefix from the raw samples held, from zero (see the module doc), after
    /// moving the samples kept to the front of the arrays.
    fn rebase(&mut self) {
        self.rebased_at = self.n;
        self.base = (self.n + 1).saturating_sub(self.len as u64);
        let from = self.pos(self.base);
        let held = (self.n - self.base) as usize;
        self.raw.copy_within(from..from + held, 0);
        self.origin = self.base;
        let (sum, count) = self.raw[..held]
            .iter()
            .filter(|y| y.is_finite())
            .fold((0.0, 0u64), |(s, c), y| (s + y, c + 1));
        if count > 0 {
            self.reference = Some(sum / count as f64);
        }
        let reference = self.reference.unwrap_or(0.0);
        self.sum1[0] = 0.0;
        self.sum2[0] = 0.0;
        self.valid[0] = 0;
        for p in 0..held {
            let y = self.raw[p];
            let (z, ok) = if y.is_finite() {
                (y - reference, 1)
            } else {
                (0.0, 0)
            };
            self.sum1[p + 1] = self.sum1[p] + z;
            self.sum2[p + 1] = self.sum2[p] + z * z;
            self.valid[p + 1] = self.valid[p] + ok;
        }
        self.counts_held = self.valid[held] != held as u64;
        for lane in 0..self.factors.len() {
            let at = lane * 2 * self.len;
            (self.term_sums[at], self.term_counts[at]) = (0.0, 0);
        }
        for p in 1..=held {
            self.append_terms(p);
        }
    }

    /// Emits every pending row whose window is complete, advancing the window policy.
    fn emit_ready(&mut self, out: &mut Vec<DavarRow>) {
        loop {
            let start = self.t - (self.w / 2) as u64;
            if start + self.w as u64 > self.n {
                return;
            }
            debug_assert!(start >= self.base);
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
        let a = self.pos(start);
        let e = a + self.w;
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
        let mut avars_out = self.spare.pop().unwrap_or_else(|| Vec::with_capacity(self.factors.len()));
        let w = self.w;
        // The factors are ascending: those with 3m ≤ W are the first `used`.
        let used = self.factors.partition_point(|&m| 3 * m <= w);
        let kept = used.min(self.summed_factors);
        let span = 2 * self.len;
        // The terms starting in [a, a + total) are those completed between the positions
        // e − total and e (the prefixes are stored where their latest term completed).
        let lanes = &self.term_sums;
        let window_sum = |i: usize, m: usize| {
            let (total, at) = (w - 2 * m + 1, i * span + e);
            (lanes[at] - lanes[at - total]).max(0.0)
        };
        let mut excluded = 0usize;
        let layout = if valid == w {
            // Every sample of the window is valid, so is every term, and no factor is left out:
            // the window's layout and divisors, made once per window.
            let slot = w % MEMO_SLOTS;
            if self.layouts[slot].window != w {
                let (memo, shared) = (&mut self.interval_of, &self.intervals);
                let points = (0..kept)
                    .map(|i| PointLayout::of(i, self.factors[i], &self.scales[i], w - 2 * self.factors[i] + 1, w, memo, shared))
                    .collect();
                self.layouts[slot] = Arc::new(RowLayout { window: w, points });
                self.inverse_divisors[slot].clear();
                self.inverse_divisors[slot].extend(
                    self.factors[..kept].iter().zip(&self.scales).map(|(&m, scale)| 1.0 / (scale.two_m2 * (w - 2 * m + 1) as f64)),
                );
            }
            // σ² = sum × 1/(2m²·terms): a product per factor, without branches or calls, straight
            // into the row (the quotients were the row's latency).
            let factors = self.factors[..kept].iter().zip(&self.inverse_divisors[slot]);
            avars_out.extend(factors.enumerate().map(|(i, (&m, &inverse))| window_sum(i, m) * inverse));
            match self.spare_layout.take() {
                Some(spare) if Arc::ptr_eq(&spare, &self.layouts[slot]) => spare,
                _ => Arc::clone(&self.layouts[slot]),
            }
        } else {
            let counts = &self.term_counts;
            let (memo, shared) = (&mut self.interval_of, &self.intervals);
            let mut points = Vec::with_capacity(used);
            for (i, (&m, scale)) in self.factors[..used].iter().zip(&self.scales).enumerate() {
                let at = i * span + e;
                let terms = (counts[at] - counts[at - (w - 2 * m + 1)]) as usize;
                excluded += w - 2 * m + 1 - terms;
                // Only the summed factors. For the shortest τ alone no point is lost: a term of a
                // longer m holds one of the first factor, so a row without the first has none.
                if terms > 0 && i < self.summed_factors {
                    // Through i64: a count is far below 2⁵³, so the value is the same, and the
                    // conversion is one instruction (u64's is a sequence).
                    avars_out.push(window_sum(i, m) / (scale.two_m2 * terms as i64 as f64));
                    points.push(PointLayout::of(i, m, scale, terms, w, memo, shared));
                }
            }
            Arc::new(RowLayout { window: 0, points })
        };
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
            avars: avars_out,
            layout: Some(layout),
        })
    }
}

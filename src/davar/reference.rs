//! The two references of the F value: σ²_ref (its denominator) and F̃ (its steady target).
//!
//! docs/design.md §3 open point 1: the seed's σ²_ref is "the overall variance" of the record. Offline that
//! is the whole record ([`record_variance`], then [`SigmaRef::Value`]: seed-exact). Live there is no
//! whole record, so [`SigmaRef::Running`] (all valid samples so far) and [`SigmaRef::Baseline`]
//! (the first N valid samples, then frozen) are offered.
//!
//! Open point 2: F̃ = 3.3 cannot be the steady mean of F when F is normalised by the same signal's
//! variance (that mean is ≈ 1, or below 1 when the record holds a noisier span). [`FTarget::Auto`]
//! learns the steady level of F as a robust median and puts F̃ at the upper edge of F's own
//! statistical band for the current window, so that a steady signal lets the window grow and only a
//! significant rise shrinks it.
//!
//! Rejected alternatives: a plain running mean of F (dragged up by the very changes it must detect);
//! a median without gating (a change lasting more than half the history becomes the new "steady").

/// How σ²_ref, the denominator of the F value, is obtained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SigmaRef {
    /// A given variance: the whole-record variance offline ([`record_variance`], seed-exact) or a
    /// value from the parameters.
    Value(f64),
    /// The population variance of all valid samples pushed so far.
    Running,
    /// The variance of the first `samples` valid samples, then frozen; running until then.
    Baseline {
        /// Number of valid samples in the baseline.
        samples: usize,
    },
}

/// Population variance of the finite values of a record (the seed's "overall variance").
///
/// Returns `None` with fewer than two finite values.
///
/// # Formula
/// ```text
/// σ² = (1/n) Σ (y[i] − ȳ)²
/// ```
/// over the n finite values y\[i\] with mean ȳ (two passes, so no cancellation).
///
/// ```
/// let v = fdavar::davar::record_variance(&[1.0, f64::NAN, 3.0]).unwrap();
/// assert_eq!(v, 1.0);
/// ```
pub fn record_variance(values: &[f64]) -> Option<f64> {
    let finite = || values.iter().copied().filter(|v| v.is_finite());
    let n = finite().count();
    if n < 2 {
        return None;
    }
    let mean = finite().sum::<f64>() / n as f64;
    Some(finite().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64)
}

/// Tracks σ²_ref sample by sample (Welford's update: stable over days of samples).
#[derive(Debug, Clone)]
pub(crate) struct SigmaRefTracker {
    mode: SigmaRef,
    n: u64,
    mean: f64,
    m2: f64,
    frozen: Option<f64>,
}

impl SigmaRefTracker {
    pub(crate) fn new(mode: SigmaRef) -> Self {
        SigmaRefTracker {
            mode,
            n: 0,
            mean: 0.0,
            m2: 0.0,
            frozen: None,
        }
    }

    /// Feeds one valid sample.
    pub(crate) fn observe(&mut self, y: f64) {
        match self.mode {
            SigmaRef::Value(_) => return,
            SigmaRef::Baseline { .. } if self.frozen.is_some() => return,
            _ => {}
        }
        self.n += 1;
        let delta = y - self.mean;
        self.mean += delta / self.n as f64;
        self.m2 += delta * (y - self.mean);
        if let SigmaRef::Baseline { samples } = self.mode {
            if self.n >= samples as u64 {
                self.frozen = self.running();
            }
        }
    }

    fn running(&self) -> Option<f64> {
        (self.n >= 2).then(|| self.m2 / self.n as f64)
    }

    /// σ²_ref now, if known and positive.
    pub(crate) fn current(&self) -> Option<f64> {
        let v = match self.mode {
            SigmaRef::Value(v) => Some(v),
            SigmaRef::Running => self.running(),
            SigmaRef::Baseline { .. } => self.frozen.or_else(|| self.running()),
        };
        v.filter(|v| *v > 0.0 && v.is_finite())
    }
}

/// The steady target F̃ of the F value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FTarget {
    /// A given F̃ (the seed's 3.3).
    Value(f64),
    /// Learned from the data (see the module doc).
    ///
    /// # Formula
    /// ```text
    /// F̃(t) = F_level · (1 + band_z · √(2 / (n − 1)))
    /// ```
    /// where F_level is the median of F over the steady rows seen so far (the first `warmup_rows`
    /// rows unconditionally, later only rows whose F lies within the band), n the number of valid
    /// samples in the window at t and √(2/(n−1)) the relative standard deviation of a variance of n
    /// white samples. Until `warmup_rows` rows are seen F̃ is unknown and the window holds.
    Auto {
        /// Width of the band in standard deviations (default 2).
        band_z: f64,
        /// Rows learned unconditionally before F̃ is used.
        warmup_rows: usize,
    },
}

/// F̃ now, from the mode and the learned level.
#[derive(Debug, Clone)]
pub(crate) struct FTargetTracker {
    mode: FTarget,
    level: RobustLevel,
}

impl FTargetTracker {
    pub(crate) fn new(mode: FTarget) -> Self {
        FTargetTracker {
            mode,
            level: RobustLevel::new(),
        }
    }

    /// F̃ for a window of `valid` samples.
    pub(crate) fn target(&self, valid: usize) -> Option<f64> {
        match self.mode {
            FTarget::Value(v) => Some(v),
            FTarget::Auto {
                band_z,
                warmup_rows,
            } => {
                if self.level.count() < warmup_rows as u64 {
                    return None;
                }
                let level = self.level.median()?;
                Some(level * (1.0 + band_z * relative_spread(valid)))
            }
        }
    }

    /// Learns from the F of one row (auto mode only; gated to steady rows after the warm-up).
    pub(crate) fn observe(&mut self, f: f64, valid: usize) {
        let FTarget::Auto {
            band_z,
            warmup_rows,
        } = self.mode
        else {
            return;
        };
        if !(f > 0.0 && f.is_finite()) {
            return;
        }
        let steady = match self.level.median() {
            Some(level) if self.level.count() >= warmup_rows as u64 => {
                let band = 1.0 + band_z * relative_spread(valid);
                f <= level * band && f >= level / band
            }
            _ => true,
        };
        if steady {
            self.level.push(f);
        }
    }
}

/// √(2/(n−1)): the relative standard deviation of the variance of n white Gaussian samples.
fn relative_spread(n: usize) -> f64 {
    (2.0 / (n.max(2) - 1) as f64).sqrt()
}

/// A streaming median of positive values on a log grid (1 % resolution), with bounded memory.
///
/// Why not an exact median: that needs every value kept; a 24 h run at 400 Hz is 35 million rows.
/// A histogram of ln(value) in bins of 0.01 anchored at the first value keeps 4001 counts and gives
/// the median to ±0.5 %, deterministically. Values beyond ±20 in ln of the anchor land in the edge
/// bins.
#[derive(Debug, Clone)]
pub struct RobustLevel {
    anchor: Option<f64>,
    counts: Vec<u64>,
    total: u64,
    /// Bin holding the lower median, and the number of values in bins below it.
    at: usize,
    below: u64,
    /// [`RobustLevel::median`], recomputed only when `at` moves: every row asks for it, and the
    /// median bin rarely changes.
    median: Option<f64>,
    /// The bin of the last value, where the next one is looked for first ([`RobustLevel::bin_of`]).
    last: usize,
    /// Per bin, the values (lo, hi) that surely fall in it ([`RobustLevel::bin_of`]), made the
    /// first time a value is looked for in that bin; empty until then.
    edges: Vec<(f64, f64)>,
}

const LEVEL_BIN: f64 = 0.01;
const LEVEL_HALF_BINS: usize = 2000;

impl Default for RobustLevel {
    fn default() -> Self {
        Self::new()
    }
}

impl RobustLevel {
    /// An empty level.
    pub fn new() -> Self {
        RobustLevel {
            anchor: None,
            counts: vec![0; 2 * LEVEL_HALF_BINS + 1],
            total: 0,
            at: LEVEL_HALF_BINS,
            below: 0,
            median: None,
            last: LEVEL_HALF_BINS,
            edges: Vec::new(),
        }
    }

    /// The bin of `value` (positive, finite) once `anchor` is set: round((ln value − anchor)/bin),
    /// clamped to the edge bins.
    ///
    /// Why the bins' intervals: consecutive rows' values (the F of windows one sample apart, the
    /// short-τ Allan variance of those windows) mostly fall in the bin of the one before or in
    /// one beside it (a bin is 1 %; a row moves its value by about 1/W), and inside a bin's
    /// interval, narrowed by a millionth of a bin on each side, no rounding of the logarithm (a
    /// few 10⁻¹⁴ bins) can place a value elsewhere: the same bin as the logarithm gives, without
    /// it. The last bin and its two neighbours are tried; each bin's interval is made once. With
    /// the last bin alone, one value in eight needed the logarithm and new edges (3 % of
    /// `fdavar analyze`); before that, the logarithm was most of a row's `push`.
    fn bin_of(&mut self, value: f64, anchor: f64) -> usize {
        let last = self.last;
        for bin in [last, last + 1, last.wrapping_sub(1)] {
            if let Some((lo, hi)) = self.interval(bin, anchor) {
                if lo <= value && value <= hi {
                    self.last = bin;
                    return bin;
                }
            }
        }
        let (_, bin) = bin_by_log(value, anchor);
        self.last = bin;
        bin
    }

    /// The values that surely fall in `bin` (see [`RobustLevel::bin_of`]); `None` for the edge
    /// bins, which hold everything beyond them, and for no bin.
    fn interval(&mut self, bin: usize, anchor: f64) -> Option<(f64, f64)> {
        if bin == 0 || bin >= 2 * LEVEL_HALF_BINS {
            return None;
        }
        if self.edges.is_empty() {
            self.edges = vec![(f64::NAN, f64::NAN); 2 * LEVEL_HALF_BINS + 1];
        }
        let edges = &mut self.edges[bin];
        if edges.0.is_nan() {
            const MARGIN: f64 = 1e-6;
            let offset = bin as f64 - LEVEL_HALF_BINS as f64;
            let edge = |side: f64| (anchor + (offset + side * (0.5 - MARGIN)) * LEVEL_BIN).exp();
            *edges = (edge(-1.0), edge(1.0));
        }
        Some(*edges)
    }

    /// Adds a value; values that are not positive and finite are ignored.
    pub fn push(&mut self, value: f64) {
        if !(value > 0.0 && value.is_finite()) {
            return;
        }
        let anchor = *self.anchor.get_or_insert_with(|| value.ln());
        let bin = self.bin_of(value, anchor);
        self.counts[bin] += 1;
        self.total += 1;
        if bin < self.at {
            self.below += 1;
        }
        let rank = (self.total - 1) / 2;
        let was = self.at;
        while self.below > rank {
            self.at -= 1;
            self.below -= self.counts[self.at];
        }
        while self.below + self.counts[self.at] <= rank {
            self.below += self.counts[self.at];
            self.at += 1;
        }
        if self.at != was || self.median.is_none() {
            let offset = self.at as f64 - LEVEL_HALF_BINS as f64;
            self.median = Some((anchor + offset * LEVEL_BIN).exp());
        }
    }

    /// Number of values pushed.
    pub fn count(&self) -> u64 {
        self.total
    }

    /// The (lower) median, to the bin resolution; `None` when empty.
    ///
    /// ```
    /// let mut l = fdavar::davar::RobustLevel::new();
    /// for v in [1.0, 2.0, 1000.0, 2.1, 1.9] { l.push(v); }
    /// assert!((l.median().unwrap() / 2.0 - 1.0).abs() < 0.01);
    /// ```
    pub fn median(&self) -> Option<f64> {
        self.median
    }
}

/// The offset round((ln value − anchor)/bin) of `value`'s bin from the anchor's, and the bin
/// (clamped to the edge bins).
fn bin_by_log(value: f64, anchor: f64) -> (f64, usize) {
    let offset = round_half_away((value.ln() - anchor) / LEVEL_BIN);
    let bin = (offset + LEVEL_HALF_BINS as f64).clamp(0.0, (2 * LEVEL_HALF_BINS) as f64) as usize;
    (offset, bin)
}

/// `x.round()`: the nearest integer, halves away from zero, the same value bit for bit (up to
/// the sign of a zero).
///
/// Why not `f64::round`: without SSE4.1's rounding instruction (the baseline x86-64 target) it is
/// a call into libm, once per DAVAR row and level (1.4 % of `fdavar davar`, `perf record`).
/// Below 2⁵² the truncation through `i64` is exact and so is `x − t`; from 2⁵² on every `f64`
/// is an integer.
fn round_half_away(x: f64) -> f64 {
    if x.is_nan() || x.abs() >= 4_503_599_627_370_496.0 {
        return x;
    }
    let t = x as i64 as f64;
    match x - t {
        f if f >= 0.5 => t + 1.0,
        f if f <= -0.5 => t - 1.0,
        _ => t,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn round_half_away_is_f64_round() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let halves = (-40..40).map(|k| k as f64 + 0.5);
        let near = [0.49999999999999994, -0.49999999999999994, 2.5 - 1e-15, 1e15 + 0.5, 4503599627370495.5];
        let big = [4503599627370496.0, -9007199254740993.0, 1e300, f64::INFINITY, f64::MIN_POSITIVE];
        let random = (0..100_000).map(|_| rng.random_range(-3000.0..3000.0) * 10f64.powi(rng.random_range(-3..3)));
        for x in halves.chain(near).chain(big).chain(random) {
            for x in [x, -x] {
                let (ours, std) = (round_half_away(x), x.round());
                assert!(ours == std && (ours != 0.0 || x.abs() < 0.5), "{x}: {ours} vs {std}");
            }
        }
        assert!(round_half_away(f64::NAN).is_nan());
    }

    #[test]
    fn a_remembered_bin_is_the_bin_of_the_logarithm() {
        // Values on and a few ulps around every bin edge within ±30 bins of the anchor, and
        // random ones, each placed right after a neighbour (so that the remembered bin is the
        // one beside or the same): the bin must be the logarithm's every time, whether found in
        // a remembered interval or not.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let anchor = 1.7e-6_f64.ln();
        let edges = (-30..30).map(|k| (anchor + (k as f64 + 0.5) * LEVEL_BIN).exp());
        let near = edges.flat_map(|e| {
            (-4..=4).map(move |ulps: i64| f64::from_bits((e.to_bits() as i64 + ulps) as u64))
        });
        let random = (0..20_000).map(|_| (anchor + rng.random_range(-0.3..0.3)).exp());
        let values: Vec<f64> = near.chain(random).collect();
        let mut level = RobustLevel::new();
        level.push(anchor.exp());
        let (mut remembered, mut placed) = (0, 0);
        for pair in values.windows(2) {
            for &v in pair {
                let last = level.last;
                let hit = [last, last + 1, last.wrapping_sub(1)]
                    .iter()
                    .any(|&b| level.edges.get(b).is_some_and(|&(lo, hi)| lo <= v && v <= hi));
                let bin = level.bin_of(v, anchor);
                assert_eq!(bin, bin_by_log(v, anchor).1, "{v:e}");
                remembered += usize::from(hit);
                placed += 1;
            }
        }
        // The fast path is taken (the test would pass vacuously otherwise).
        assert!(remembered > placed / 4, "{remembered} of {placed}");
    }

    #[test]
    fn robust_level_matches_the_exact_median() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut l = RobustLevel::new();
        let mut all = Vec::new();
        for _ in 0..10_001 {
            let v: f64 = rng.random_range(0.5..4.0);
            l.push(v);
            all.push(v);
        }
        all.sort_by(f64::total_cmp);
        let exact = all[5000];
        assert!((l.median().unwrap() / exact - 1.0).abs() < 0.006);
    }

    #[test]
    fn sigma_ref_modes() {
        let data = [1.0, 3.0, 1.0, 3.0, 10.0, -6.0];
        let mut running = SigmaRefTracker::new(SigmaRef::Running);
        let mut base = SigmaRefTracker::new(SigmaRef::Baseline { samples: 4 });
        let mut fixed = SigmaRefTracker::new(SigmaRef::Value(2.5));
        assert_eq!(running.current(), None);
        for (i, &y) in data.iter().enumerate() {
            running.observe(y);
            base.observe(y);
            fixed.observe(y);
            let sofar = record_variance(&data[..=i]);
            assert_eq!(
                running.current().map(|v| (v * 1e12).round()),
                sofar.map(|v| (v * 1e12).round())
            );
            assert_eq!(fixed.current(), Some(2.5));
        }
        assert_eq!(
            base.current(),
            Some(1.0),
            "frozen after the first four samples"
        );
        assert!(running.current().unwrap() > 20.0);
    }

    #[test]
    fn f_target_auto_learns_then_ignores_outliers() {
        let mut t = FTargetTracker::new(FTarget::Auto {
            band_z: 2.0,
            warmup_rows: 10,
        });
        for _ in 0..9 {
            t.observe(0.5, 201);
        }
        assert_eq!(t.target(201), None, "still warming up");
        t.observe(0.5, 201);
        let target = t.target(201).unwrap();
        assert!(
            (target / (0.5 * (1.0 + 2.0 * 0.1)) - 1.0).abs() < 0.01,
            "{target}"
        );
        for _ in 0..100 {
            t.observe(5.0, 201);
        }
        assert_eq!(
            t.target(201).unwrap(),
            target,
            "a change does not move the steady level"
        );
        assert_eq!(
            FTargetTracker::new(FTarget::Value(3.3)).target(2),
            Some(3.3)
        );
    }
}

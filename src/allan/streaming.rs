//! Streaming cumulative overlapping Allan variance: push one rate sample, read every τ at any time.
//!
//! The live node needs the Allan variance of the whole run so far (for the whole-run coefficients)
//! without keeping the run in memory. Each new sample completes exactly one overlapping term per
//! averaging factor, so the accumulator keeps, per factor, the running sum of squared second
//! differences and the term count, plus a ring buffer of the last 2·m_max + 1 phase values: O(K)
//! work per sample and O(K + m_max) memory for K factors.
//!
//! It equals the batch [`super::oavar_rate_counted`] exactly (same phase, same terms, added in the
//! same order to the same interleaved partial sums), including the terms it leaves out for invalid
//! samples. Both integrate the rate
//! minus the first valid sample, which keeps the phase of a biased axis (an accelerometer feeling
//! g) small, so no precision is lost over hours. A running sum never subtracts here, so it does
//! not drift; its relative rounding error after n terms is below n·ε (2e-9 after 24 h at 100 Hz).
//!
//! EDF: the record itself is not kept, so the noise type per τ comes from the local log-log slope
//! μ of the variance between neighbouring factors (σ² ∝ τ^μ, α = −μ − 1, μ ≈ −2 read as white PM);
//! the batch path identifies it from the data (lag-1 ACF), so EDFs may differ slightly.

use super::rate::{pairwise, INTERLEAVE};
use super::{edf, with_confidence, AllanPoint, Estimator};

/// Cumulative overlapping Allan variance of a rate stream at fixed averaging factors.
#[derive(Debug, Clone)]
pub struct OavarAccumulator {
    tau0: f64,
    factors: Vec<usize>,
    /// Ring of the last `ring.len()` phase values, indexed by phase index modulo the length.
    ring: Vec<f64>,
    /// Ring of the count of invalid samples before each phase index (same indexing).
    bad_ring: Vec<usize>,
    /// Per factor, the interleaved partial sums of the batch path: term i goes to sum i mod 8.
    sums: Vec<[f64; INTERLEAVE]>,
    terms: Vec<usize>,
    skipped: Vec<usize>,
    /// Phase points so far (samples + 1 once the first sample arrived).
    len: usize,
    phase: f64,
    bad: usize,
    reference: Option<f64>,
}

/// Why an accumulator could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum StreamingError {
    /// τ0 must be positive and finite.
    #[error("sample period tau0 = {0} s is not positive and finite")]
    BadTau0(f64),
    /// Averaging factors must be at least 1.
    #[error("averaging factor 0 is not allowed")]
    ZeroFactor,
}

impl OavarAccumulator {
    /// An empty accumulator for period `tau0` seconds and the given averaging factors (sorted, deduplicated).
    ///
    /// # Errors
    /// [`StreamingError::BadTau0`] for a non-positive τ0, [`StreamingError::ZeroFactor`] for m = 0.
    pub fn new(tau0: f64, factors: &[usize]) -> Result<Self, StreamingError> {
        if !(tau0.is_finite() && tau0 > 0.0) {
            return Err(StreamingError::BadTau0(tau0));
        }
        if factors.contains(&0) {
            return Err(StreamingError::ZeroFactor);
        }
        let mut factors = factors.to_vec();
        factors.sort_unstable();
        factors.dedup();
        let ring_len = 2 * factors.last().copied().unwrap_or(0) + 1;
        let k = factors.len();
        Ok(OavarAccumulator {
            tau0,
            factors,
            ring: vec![0.0; ring_len],
            bad_ring: vec![0; ring_len],
            sums: vec![[0.0; INTERLEAVE]; k],
            terms: vec![0; k],
            skipped: vec![0; k],
            len: 0,
            phase: 0.0,
            bad: 0,
            reference: None,
        })
    }

    /// Adds one rate sample (NaN or ±∞ = invalid: terms touching it are left out and counted).
    pub fn push(&mut self, y: f64) {
        if self.len == 0 {
            self.store(0.0, 0);
        }
        if y.is_finite() {
            let reference = *self.reference.get_or_insert(y);
            self.phase += self.tau0 * (y - reference);
        } else {
            self.bad += 1;
        }
        self.store(self.phase, self.bad);
        let n = self.len; // phase points now; the newest has index n − 1
        let r = self.ring.len();
        let newest = (n - 1) % r;
        for (k, &m) in self.factors.iter().enumerate() {
            if n < 2 * m + 1 {
                break;
            }
            let mid = (n - 1 - m) % r;
            let oldest = (n - 1 - 2 * m) % r;
            if self.bad_ring[newest] == self.bad_ring[oldest] {
                let d = self.ring[newest] - 2.0 * self.ring[mid] + self.ring[oldest];
                self.sums[k][(n - 1 - 2 * m) % INTERLEAVE] += d * d;
                self.terms[k] += 1;
            } else {
                self.skipped[k] += 1;
            }
        }
    }

    fn store(&mut self, phase: f64, bad: usize) {
        let r = self.ring.len();
        self.ring[self.len % r] = phase;
        self.bad_ring[self.len % r] = bad;
        self.len += 1;
    }

    /// Rate samples pushed so far.
    pub fn samples(&self) -> usize {
        self.len.saturating_sub(1)
    }

    /// The averaging factors, ascending.
    pub fn factors(&self) -> &[usize] {
        &self.factors
    }

    /// Terms left out so far, per factor (same order as [`Self::factors`]).
    pub fn skipped(&self) -> &[usize] {
        &self.skipped
    }

    /// The current estimates (factors without a term yet are left out), with EDF and 68.3 % interval.
    pub fn points(&self) -> Vec<AllanPoint> {
        let raw: Vec<(usize, f64, usize)> = self
            .factors
            .iter()
            .zip(&self.sums)
            .zip(&self.terms)
            .filter(|(_, &t)| t > 0)
            .map(|((&m, &s), &t)| {
                let tau = m as f64 * self.tau0;
                (m, pairwise(s) / (2.0 * tau * tau * t as f64), t)
            })
            .collect();
        let shape = Estimator::Oadev.shape();
        (0..raw.len())
            .map(|i| {
                let (m, avar, terms) = raw[i];
                let alpha = slope_alpha(&raw, i);
                with_confidence(
                    m,
                    m as f64 * self.tau0,
                    avar,
                    terms,
                    alpha,
                    shape,
                    terms + 2 * m,
                    edf::ONE_SIGMA,
                )
            })
            .collect()
    }
}

/// α from the log-log slope μ of σ²(τ) around point `i`: α = −μ − 1, clamped to −2 ..= 2.
fn slope_alpha(raw: &[(usize, f64, usize)], i: usize) -> i32 {
    let lo = i.saturating_sub(1);
    let hi = (i + 1).min(raw.len() - 1);
    if lo == hi || raw[lo].1 <= 0.0 || raw[hi].1 <= 0.0 {
        return 0;
    }
    let mu = (raw[hi].1 / raw[lo].1).ln() / (raw[hi].0 as f64 / raw[lo].0 as f64).ln();
    if mu < -1.5 {
        2
    } else {
        (-mu - 1.0).round().clamp(-2.0, 1.0) as i32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        // Chunked streaming equals the batch result exactly, whenever it is read.
        #[test]
        fn streaming_equals_batch(y in prop::collection::vec(-10f64..10.0, 1..150), holes in prop::collection::vec(0usize..150, 0..3), read_at in 0usize..150) {
            let mut y = y;
            let n = y.len();
            for h in &holes { y[h % n] = f64::NAN; }
            let factors = [1, 2, 3, 5, 8, 13, 21, 34];
            let mut acc = OavarAccumulator::new(0.01, &factors).unwrap();
            for (i, &v) in y.iter().enumerate() {
                acc.push(v);
                if i + 1 == n || i == read_at {
                    let batch = super::super::oavar_rate_counted(&y[..=i], 0.01, &factors);
                    let stream = acc.points();
                    prop_assert_eq!(batch.len(), stream.len());
                    for (b, s) in batch.iter().zip(&stream) {
                        prop_assert_eq!(b.point.m, s.m);
                        prop_assert_eq!(b.point.terms, s.terms);
                        prop_assert_eq!(b.point.avar.to_bits(), s.avar.to_bits());
                    }
                    let skipped: Vec<usize> = batch.iter().map(|b| b.skipped).collect();
                    let stream_skipped: Vec<usize> = acc.factors().iter().zip(acc.skipped()).filter(|(m, _)| batch.iter().any(|b| b.point.m == **m)).map(|(_, s)| *s).collect();
                    prop_assert_eq!(skipped, stream_skipped);
                }
            }
        }
    }

    #[test]
    fn rejects_bad_settings() {
        assert_eq!(
            OavarAccumulator::new(0.0, &[1]).unwrap_err(),
            StreamingError::BadTau0(0.0)
        );
        assert_eq!(
            OavarAccumulator::new(0.1, &[0, 1]).unwrap_err(),
            StreamingError::ZeroFactor
        );
    }
}

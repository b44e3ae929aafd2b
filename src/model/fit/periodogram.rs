//! The record's periodogram: where its lines are (candidates of the frequency scans,
//! [`Periodogram::peaks`]) and whether a fitted line is one ([`Periodogram::line_support`]).
//!
//! Why a line is checked here and not only on the Allan variance: a sinusoid's Allan signature is
//! a bump, and so is a Gauss–Markov process's; on a record of a few hundred correlation times the
//! nulls that tell them apart sit where the Allan variance has a few degrees of freedom, so either
//! can fit the bump. In the spectrum they differ by kind: a sinusoid is one line standing out of
//! its neighbourhood, a Gauss–Markov process a smooth shoulder.

use crate::model::timedomain::Plans;

/// How many peaks of the periodogram [`line_candidates`] hands to the frequency scans.
pub(super) const LINE_CANDIDATES: usize = 3;

/// Largest probability that noise alone, without a line, stands out as much as a supported line
/// ([`Periodogram::line_support`]).
pub const LINE_ALPHA: f64 = 1e-3;

/// Half the width, as a share of the frequency, of the bins [`Periodogram::line_support`] looks
/// for a line in: the frequency a weak line is fitted at on the Allan variance is off by up to
/// this much (the 10 % tolerance of docs/model.md's power curves), and a real line is a narrow
/// band (the ADIS16405's accel lines: 0.537–0.586 Hz).
pub const LINE_WIDTH: f64 = 0.1;

/// Least number of bins either side of a line's frequency that [`line_reach`] gives: the Hann
/// taper spreads a line over its bin and the two beside it.
pub const LINE_BINS: usize = 2;

/// How far, in bins, from a line at `frequency_hz` a search for it reads, for `bins_per_hz` bins
/// per Hz: max([`LINE_BINS`], [`LINE_WIDTH`]·f). Why a share of f: the Allan fit places a line
/// beside a stronger one only roughly (a second line at 0.07 Hz beside one at 0.05 Hz, 20 min:
/// fitted at 0.0741 Hz, 5 bins off), and a real line is a narrow band. Read by
/// [`Periodogram::line_support`] and [`crate::model::timedomain::Whitened::line_power`], so that
/// the two look in the same bins.
pub fn line_reach(frequency_hz: f64, bins_per_hz: f64) -> f64 {
    (LINE_WIDTH * frequency_hz * bins_per_hz).max(LINE_BINS as f64)
}

/// Least number of reference bins around a frequency for [`Periodogram::line_support`] to decide.
const MIN_REFERENCE_BINS: usize = 24;

/// The [`LINE_CANDIDATES`] strongest peaks of the periodogram of `series` (see
/// [`Periodogram::peaks`]); empty when the series is too short to have one.
pub(super) fn line_candidates(series: &[f64], tau0: f64, plans: &Plans) -> Vec<(f64, f64)> {
    Periodogram::of(series, tau0, plans).map_or_else(Vec::new, |p| p.peaks(LINE_CANDIDATES))
}

/// The periodogram of a record: its power per frequency bin.
#[derive(Debug, Clone)]
pub struct Periodogram {
    power: Vec<f64>,
    bin_hz: f64,
}

/// How far a fitted line stands out of the periodogram around it ([`Periodogram::line_support`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineSupport {
    /// The largest power within the line's bins over the median power of its neighbourhood.
    pub ratio: f64,
    /// The ratio noise alone exceeds with probability [`LINE_ALPHA`].
    pub threshold: f64,
    /// The ratio the largest bin of the whole periodogram exceeds with probability [`LINE_ALPHA`]
    /// on noise alone: the threshold for a line whose frequency was searched everywhere (a
    /// candidate's scan starts from the periodogram's strongest peaks, [`Periodogram::peaks`]; the
    /// largest of 6·10⁴ bins of a smooth spectrum is about 17 times the median, above `threshold`
    /// for a low frequency, whose line bins are few: about 12 for 5 bins).
    pub threshold_anywhere: f64,
}

impl LineSupport {
    /// Whether the line stands out of its neighbourhood: `ratio ≥ threshold`.
    pub fn holds(&self) -> bool {
        self.ratio >= self.threshold
    }

    /// Whether the line stands out even as the strongest of the whole periodogram would by chance:
    /// `ratio ≥ threshold_anywhere`.
    pub fn holds_anywhere(&self) -> bool {
        self.ratio >= self.threshold_anywhere
    }
}

impl Periodogram {
    /// The periodogram of `series`, sampled every `tau0` s; `None` for fewer than 16 valid
    /// samples or an invalid `tau0`.
    ///
    /// # Formula
    /// ```text
    /// P[k] = |Σ (y[n] − ȳ)·e^(−2πikn/N)|²,   bin k at k/(N·τ0) Hz
    /// ```
    /// Invalid samples count as the mean; the series is zero-padded to a fast length
    /// ([`crate::model::timedomain::fast_len`] of a length at least the record's). The transform
    /// comes from `plans`, which the axes of a record share (one plan per length).
    pub fn of(series: &[f64], tau0: f64, plans: &Plans) -> Option<Self> {
        let valid = series.iter().filter(|v| v.is_finite()).count();
        if valid < 16 || tau0.is_nan() || tau0 <= 0.0 {
            return None;
        }
        let mean = series.iter().filter(|v| v.is_finite()).sum::<f64>() / valid as f64;
        // The fast length at or above the record's: fast_len rounds down.
        let mut n = series.len();
        while crate::model::timedomain::fast_len(n) < series.len() {
            n += n / 64 + 1;
        }
        let n = crate::model::timedomain::fast_len(n);
        let mut input: Vec<f64> = series.iter().map(|v| if v.is_finite() { v - mean } else { 0.0 }).collect();
        input.resize(n, 0.0);
        let fft = plans.transform(n);
        let mut spectrum = fft.make_output_vec();
        fft.process(&mut input, &mut spectrum).ok()?;
        Some(Self {
            power: spectrum.iter().map(|c| c.norm_sqr()).collect(),
            bin_hz: 1.0 / (n as f64 * tau0),
        })
    }

    /// The `count` strongest local maxima (DC and the first bin left out), as (frequency, bin
    /// width) in Hz, strongest first.
    ///
    /// # Formula
    /// ```text
    /// f = (k + δ)·bin,   δ = ½(a − c)/(a − 2b + c)
    /// ```
    /// with a, b, c the log power at bins k − 1, k, k + 1 (the parabola through them; Quinn 1994
    /// for the family of such interpolators). On noise alone the peaks are anywhere: they are
    /// candidates, and the scan keeps what fits best.
    pub fn peaks(&self, count: usize) -> Vec<(f64, f64)> {
        let power = &self.power;
        let mut peaks: Vec<(f64, usize)> = (2..power.len().saturating_sub(1))
            .filter(|&k| power[k] > power[k - 1] && power[k] >= power[k + 1])
            .map(|k| (power[k], k))
            .collect();
        peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
        peaks
            .iter()
            .take(count)
            .map(|&(_, k)| {
                let (a, b, c) = (power[k - 1].ln(), power[k].ln(), power[k + 1].ln());
                let curvature = a - 2.0 * b + c;
                let delta = if curvature < 0.0 { (0.5 * (a - c) / curvature).clamp(-0.5, 0.5) } else { 0.0 };
                ((k as f64 + delta) * self.bin_hz, self.bin_hz)
            })
            .collect()
    }

    /// Whether a line at `frequency_hz` stands out of its neighbourhood; `None` when the
    /// neighbourhood is too small to tell (a line of few periods in the record, or near Nyquist).
    ///
    /// The line's bins are those within max(2 bins, 10 % of f) of f ([`LINE_WIDTH`]: a fitted
    /// frequency is not exact, and a real line is a narrow band); its neighbourhood the bins from
    /// f/2 to 2f outside three times that, at least 24 of them (a line of 25 periods or more in
    /// the record). Why the median of two octaves: it ignores other lines, and a coloured spectrum
    /// moves it little — on a random walk's f⁻² the median bin, at about 1.25 f, is 0.64 of the
    /// power at f, which only makes a line easier to accept.
    ///
    /// # Formula
    /// Without a line each ordinate is S(f)·E, E exponential of mean 1, whose median is S·ln 2; so
    /// the largest of m line bins exceeds r times the neighbourhood's median with probability
    /// ```text
    /// p = 1 − (1 − 2^(−r))^m,   threshold r at p = LINE_ALPHA
    /// ```
    /// with m the line's bins (`threshold`), or every bin of the periodogram (`threshold_anywhere`).
    /// (Schuster's periodogram test, Fisher's g for the largest of several ordinates; here against
    /// a local median, robust to the colour of the noise and to other lines).
    pub fn line_support(&self, frequency_hz: f64) -> Option<LineSupport> {
        let last = self.power.len().checked_sub(1)?;
        let k = frequency_hz / self.bin_hz;
        if !k.is_finite() || k <= 0.0 {
            return None;
        }
        let half = line_reach(frequency_hz, 1.0 / self.bin_hz);
        let (lo, hi) = (((k - half).ceil().max(1.0)) as usize, ((k + half).floor() as usize).min(last));
        let (rlo, rhi) = (((k / 2.0).ceil().max(1.0)) as usize, ((k * 2.0).floor() as usize).min(last));
        if lo > hi || rlo > rhi {
            return None;
        }
        let mut reference: Vec<f64> =
            (rlo..=rhi).filter(|&i| (i as f64 - k).abs() > 3.0 * half).map(|i| self.power[i]).collect();
        if reference.len() < MIN_REFERENCE_BINS {
            return None;
        }
        let middle = reference.len() / 2;
        let median = *reference.select_nth_unstable_by(middle, f64::total_cmp).1;
        if median.is_nan() || median <= 0.0 {
            return None;
        }
        let peak = self.power[lo..=hi].iter().copied().fold(0.0, f64::max);
        // p = 1 − (1 − 2^(−r))^m = α  ⇔  2^(−r) = 1 − (1 − α)^(1/m).
        let threshold_of = |searched: usize| -(-((-LINE_ALPHA).ln_1p() / searched as f64).exp_m1()).log2();
        Some(LineSupport {
            ratio: peak / median,
            threshold: threshold_of(hi - lo + 1),
            threshold_anywhere: threshold_of(self.power.len()),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::{Effect, GaussMarkov, SimContext, Sinusoid};
    use rand::SeedableRng;

    fn simulated(effects: &[&dyn Effect], seed: u64) -> Vec<f64> {
        let ctx = SimContext { dt: 0.01, white_sigma: 0.0, temperature_c: None, accel: None };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut y: Vec<f64> = (0..120_000).map(|_| 0.0).collect();
        crate::model::effects::White::new(1e-3).unwrap().simulate(&ctx, &mut rng, &mut y);
        for e in effects {
            e.simulate(&ctx, &mut rng, &mut y);
        }
        y
    }

    #[test]
    fn a_line_stands_out_and_a_gauss_markov_shoulder_does_not() {
        // 20 min at 100 Hz over white noise of 10⁻² rad/s per sample: a 0.05 Hz line about 6
        // times the white AVAR at its peak (7.4 s), and a Gauss–Markov process of T = 3 s whose
        // long-τ level is 8.6 times the white one; a sinusoid fitted to the latter's Allan bump
        // sits near 0.05 Hz.
        let line = Sinusoid::new(1.2e-3, 0.05).unwrap();
        let gm = GaussMarkov::new(1.2e-3, 3.0).unwrap();
        for seed in 0..5 {
            let with_line = Periodogram::of(&simulated(&[&line], seed), 0.01, &Plans::default()).unwrap();
            let s = with_line.line_support(0.05).unwrap();
            assert!(s.holds() && s.holds_anywhere(), "seed {seed}: {s:?}");
            let with_gm = Periodogram::of(&simulated(&[&gm], seed), 0.01, &Plans::default()).unwrap();
            for f in [0.03, 0.05, 0.08] {
                let s = with_gm.line_support(f).unwrap();
                assert!(!s.holds(), "seed {seed}, {f} Hz: {s:?}");
            }
        }
    }

    #[test]
    fn the_strongest_peak_of_noise_is_not_a_line_anywhere() {
        // A candidate's frequency comes from the periodogram's strongest peaks: on white noise
        // alone the strongest of 60 000 bins is about (ln 60 000 + γ)/ln 2 ≈ 17 times the median,
        // below the whole periodogram's threshold of log2(60 000/α) ≈ 26 — and above a local
        // threshold of a few bins (log2(5/α) ≈ 12).
        for seed in 0..20 {
            let p = Periodogram::of(&simulated(&[], seed), 0.01, &Plans::default()).unwrap();
            let (f, _) = p.peaks(1)[0];
            let Some(s) = p.line_support(f) else { continue };
            assert!((10.0..25.0).contains(&s.ratio), "seed {seed}, {f} Hz: {s:?}");
            assert!(!s.holds_anywhere(), "seed {seed}, {f} Hz: {s:?}");
            let bins = p.power.len() as f64;
            assert!((s.threshold_anywhere - (bins / LINE_ALPHA).log2()).abs() < 0.01, "{s:?}");
        }
    }

    #[test]
    fn a_line_of_few_periods_is_not_judged() {
        let p = Periodogram::of(&simulated(&[], 1), 0.01, &Plans::default()).unwrap();
        // 0.004 Hz: 4.8 periods in 20 min, an octave around it holds about 3 bins.
        assert_eq!(p.line_support(0.004), None);
        assert!(p.line_support(1.0).is_some());
    }
}

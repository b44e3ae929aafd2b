//! Equivalent degrees of freedom (Greenhall's algorithm) and χ² confidence intervals.
//!
//! An Allan-family estimate is a sum of squared, correlated differences; its distribution is close
//! to a scaled χ² whose degrees of freedom (the EDF) depend on the estimator, the averaging factor,
//! the record length and the power-law noise type α. Greenhall's generalized algorithm computes
//! that EDF for every variance built from d-th differences of phase (d = 2: Allan, 3: Hadamard),
//! overlapped or not, modified or not, from the exact autocovariance of the differences. It is what
//! Stable32 uses, and it reproduces Stable32's confidence bounds on the Cs5071A reference tables.
//!
//! Rejected alternative: the closed forms of NIST SP 1065 Table 5 (Howe–Allan–Barnes) cover only
//! OADEV with five noise types, are approximations, and disagree with Stable32 by several percent
//! at large τ.
//!
//! # References
//! - Greenhall C. A., Riley W. J., "Uncertainty of stability variances based on finite differences",
//!   Proc. 35th PTTI Meeting, 2003 (the algorithm, Eqs. 7–13 and Tables 1–3).
//! - Riley W. J., "Handbook of Frequency Stability Analysis", NIST SP 1065, 2008, §5.3 (χ² intervals).

use statrs::distribution::{ChiSquared, Continuous, ContinuousCDF};

/// The shape of a variance for Greenhall's EDF: difference order, overlap and modification.
///
/// Why a separate type: the EDF does not depend on which named estimator produced a variance, only
/// on these three facts, and keeping them apart lets a new estimator reuse the algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VarianceShape {
    /// Order of the phase difference: 2 for Allan variances, 3 for Hadamard variances.
    pub d: u32,
    /// True when the estimator uses every start index (stride 1), false for stride m.
    pub overlapping: bool,
    /// True for modified variances (phase averaged over m samples before differencing).
    pub modified: bool,
}

/// Largest J for which the basic sum is evaluated directly (Greenhall's J_max).
const J_MAX: f64 = 100.0;

/// Greenhall's equivalent degrees of freedom of a variance estimate.
///
/// Use it for any estimate built from d-th differences of `n` phase points at averaging factor `m`
/// under power-law noise S_y(f) ∝ f^α. Returns `None` when the combination is outside the algorithm
/// (α + 2d ≤ 1, i.e. a noise too red for the difference order, α outside −4..=2, or fewer points
/// than one difference needs, N < L).
///
/// # Formula
/// ```text
/// L = m/F + m·d,  M = 1 + ⌊S·(N − L)/m⌋,  J = min(M, (d+1)·S),  r = M/S
/// BasicSum(J, M, S, F) = sz(0)² + (1 − J/M)·sz(J/S)² + 2·Σ_{j=1}^{J−1} (1 − j/M)·sz(j/S)²
/// 1/edf = BasicSum / (M·sz(0)²)                        when J ≤ J_max
/// 1/edf = (a0 − a1/r)/r   (Tables 1, 2; Table 3 scale for α = 1)  when J > J_max, r > d + 1
/// 1/edf = BasicSum(J_max, J_max, J_max/r, F′) / (J_max·sz(0)²)   otherwise
/// sz(t) = Σ_k (−1)^k·C(2d, d+k)·sx(t + k),  sx(t) = F²·(2·sw(t) − sw(t − 1/F) − sw(t + 1/F))
/// sw(t) = −|t|, t²ln|t|, |t|³, t⁴ln|t|, |t|⁵, t⁶ln|t|, |t|⁷   for α = 2, 1, 0, −1, −2, −3, −4
/// ```
/// where N = `n` phase points, F = 1 for modified variances and m otherwise, S = m when
/// overlapping and 1 otherwise, and F = ∞ means sx(t) = sw(t) with α + 2 (sign conventions of sw
/// drop out because only squares of sz enter).
///
/// # References
/// Greenhall C. A., Riley W. J., "Uncertainty of stability variances based on finite differences",
/// Proc. 35th PTTI, 2003.
///
/// ```
/// use fdavar::allan::edf::{greenhall_edf, VarianceShape};
/// // White PM, OADEV at m = 1 on the Cs5071A record (556 990 points): M = 556 988 terms and
/// // edf = M / (C(8,4)/C(4,2)² − 1/M) ≈ M·18/35, which gives Stable32's bound 3.3128e-10.
/// let oadev = VarianceShape { d: 2, overlapping: true, modified: false };
/// let edf = greenhall_edf(2, oadev, 1, 556_990).unwrap();
/// assert!((edf - 556_988.0 * 18.0 / 35.0).abs() < 1.0);
/// ```
pub fn greenhall_edf(alpha: i32, shape: VarianceShape, m: usize, n: usize) -> Option<f64> {
    let d = shape.d;
    if !(1..=3).contains(&d) || !(-4..=2).contains(&alpha) || alpha + 2 * d as i32 <= 1 || m == 0 {
        return None;
    }
    let mf = m as f64;
    let df = f64::from(d);
    let f = if shape.modified { 1.0 } else { mf };
    let s = if shape.overlapping { mf } else { 1.0 };
    let l = mf / f + mf * df;
    if (n as f64) < l {
        return None;
    }
    let big_m = 1.0 + (s * (n as f64 - l) / mf).floor();
    let j = big_m.min((df + 1.0) * s);
    let r = big_m / s;
    let sz0 = |f: f64| sz(0.0, f, alpha, d);
    let inv_edf = if shape.modified {
        // Case 1: modified variances, every α.
        if j <= J_MAX {
            basic_sum(j, big_m, s, 1.0, alpha, d) / (sz0(1.0).powi(2) * big_m)
        } else if r > df + 1.0 {
            let (a0, a1) = table1(alpha, d)?;
            (a0 - a1 / r) / r
        } else {
            basic_sum(J_MAX, J_MAX, J_MAX / r, 1.0, alpha, d) / (sz0(1.0).powi(2) * J_MAX)
        }
    } else if alpha <= 0 {
        // Case 2: unmodified, α ≤ 0.
        if j <= J_MAX {
            let fp = if mf * (df + 1.0) <= J_MAX {
                mf
            } else {
                f64::INFINITY
            };
            basic_sum(j, big_m, s, fp, alpha, d) / (sz0(fp).powi(2) * big_m)
        } else if r > df + 1.0 {
            let (a0, a1) = table2(alpha, d)?;
            (a0 - a1 / r) / r
        } else {
            let inf = f64::INFINITY;
            basic_sum(J_MAX, J_MAX, J_MAX / r, inf, alpha, d) / (sz0(inf).powi(2) * J_MAX)
        }
    } else if alpha == 1 {
        // Case 3: unmodified, flicker PM (the variance depends on ln m).
        if j <= J_MAX {
            basic_sum(j, big_m, s, mf, 1, d) / (sz0(mf).powi(2) * big_m)
        } else {
            let (b0, b1) = table3(d);
            let scale = (b0 + b1 * mf.ln()).powi(2);
            if r > df + 1.0 {
                let (a0, a1) = table2(alpha, d)?;
                (a0 - a1 / r) / (scale * r)
            } else {
                let mp = J_MAX / r;
                basic_sum(J_MAX, J_MAX, mp, mp, 1, d) / (scale * J_MAX)
            }
        }
    } else {
        // Case 4: unmodified, white PM.
        let k = r.ceil();
        if k <= df {
            // Few differences: the basic sum is exact and J ≤ (d+1)·S stays small enough here.
            basic_sum(j, big_m, s, mf, alpha, d) / (sz0(mf).powi(2) * big_m)
        } else {
            let a0 = binomial(4 * d, 2 * d) / binomial(2 * d, d).powi(2);
            let a1 = df / 2.0;
            (a0 - a1 / r) / big_m
        }
    };
    (inv_edf.is_finite() && inv_edf > 0.0).then(|| 1.0 / inv_edf)
}

/// Greenhall's basic sum, Eq. (10).
fn basic_sum(j: f64, big_m: f64, s: f64, f: f64, alpha: i32, d: u32) -> f64 {
    let first = sz(0.0, f, alpha, d).powi(2);
    let second = (1.0 - j / big_m) * sz(j / s, f, alpha, d).powi(2);
    let third: f64 = (1..j as usize)
        .map(|jj| {
            let jj = jj as f64;
            2.0 * (1.0 - jj / big_m) * sz(jj / s, f, alpha, d).powi(2)
        })
        .sum();
    first + second + third
}

/// Eq. (9): the d-th difference of sx.
fn sz(t: f64, f: f64, alpha: i32, d: u32) -> f64 {
    let d = d as i32;
    (-d..=d)
        .map(|k| {
            let c = binomial((2 * d) as u32, (d + k) as u32);
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            sign * c * sx(t + f64::from(k), f, alpha)
        })
        .sum::<f64>()
}

/// Eq. (8): the filter of the phase samples (F = ∞: no averaging filter, one more integration).
fn sx(t: f64, f: f64, alpha: i32) -> f64 {
    if f.is_infinite() {
        return sw(t, alpha + 2);
    }
    f * f * (2.0 * sw(t, alpha) - sw(t - 1.0 / f, alpha) - sw(t + 1.0 / f, alpha))
}

/// Eq. (7): the generalized autocovariance of power-law noise (signs dropped: only squares enter).
fn sw(t: f64, alpha: i32) -> f64 {
    let a = t.abs();
    let tlog = |p: i32| if a == 0.0 { 0.0 } else { t.powi(p) * a.ln() };
    match alpha {
        2 => -a,
        1 => tlog(2),
        0 => a.powi(3),
        -1 => tlog(4),
        -2 => a.powi(5),
        -3 => tlog(6),
        _ => a.powi(7),
    }
}

fn binomial(n: u32, k: u32) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * f64::from(n - i) / f64::from(i + 1))
}

/// Table 1 (modified variances): (a0, a1) by α (rows 2 … −4) and d (columns 1 … 3).
fn table1(alpha: i32, d: u32) -> Option<(f64, f64)> {
    const T: [[(f64, f64); 3]; 7] = [
        [
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 1.0 / 2.0),
            (22.0 / 25.0, 2.0 / 3.0),
        ],
        [(0.840, 0.345), (0.997, 0.616), (1.141, 0.843)],
        [(1.079, 0.368), (1.033, 0.607), (1.184, 0.848)],
        [(f64::NAN, f64::NAN), (1.048, 0.534), (1.180, 0.816)],
        [(f64::NAN, f64::NAN), (1.302, 0.535), (1.175, 0.777)],
        [(f64::NAN, f64::NAN), (f64::NAN, f64::NAN), (1.194, 0.703)],
        [(f64::NAN, f64::NAN), (f64::NAN, f64::NAN), (1.489, 0.702)],
    ];
    table_entry(&T, alpha, d)
}

/// Table 2 (unmodified variances): (a0, a1) by α and d.
fn table2(alpha: i32, d: u32) -> Option<(f64, f64)> {
    const T: [[(f64, f64); 3]; 7] = [
        [
            (3.0 / 2.0, 1.0 / 2.0),
            (35.0 / 18.0, 1.0),
            (231.0 / 100.0, 3.0 / 2.0),
        ],
        [(78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)],
        [
            (2.0 / 3.0, 1.0 / 6.0),
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 1.0 / 2.0),
        ],
        [(f64::NAN, f64::NAN), (0.852, 0.375), (0.997, 0.617)],
        [(f64::NAN, f64::NAN), (1.079, 0.368), (1.033, 0.607)],
        [(f64::NAN, f64::NAN), (f64::NAN, f64::NAN), (1.053, 0.553)],
        [(f64::NAN, f64::NAN), (f64::NAN, f64::NAN), (1.302, 0.535)],
    ];
    table_entry(&T, alpha, d)
}

/// Table 3 (unmodified, α = 1): (b0, b1) by d.
fn table3(d: u32) -> (f64, f64) {
    [(6.0, 4.0), (15.23, 12.0), (47.8, 40.0)][(d - 1) as usize]
}

fn table_entry(t: &[[(f64, f64); 3]; 7], alpha: i32, d: u32) -> Option<(f64, f64)> {
    let row = usize::try_from(2 - alpha).ok()?;
    let e = *t.get(row)?.get(usize::try_from(d).ok()?.checked_sub(1)?)?;
    (!e.0.is_nan()).then_some(e)
}

/// The two-sided 68.27 % ("one sigma") confidence level, erf(1/√2).
pub const ONE_SIGMA: f64 = 0.682_689_492_137_085_9;

/// How a χ² quantile is computed: the crate's one χ² inversion, with the two methods its outputs
/// were made with.
///
/// Two methods, not one, because the numbers already printed depend on each: `fdavar allan`'s
/// bounds and the fit's 68.3 % bounds (its CSV and figures) on the polished quantile, the DAVAR
/// engine's intervals and change detector on statrs' own inversion. Moving the engine would change
/// its rows' bounds in the last digits (its windows keep the EDF far below the millions where
/// statrs' inversion breaks down, see [`crate::model::measure::chi2_interval`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Chi2Inversion {
    /// Wilson–Hilferty start, polished by Newton steps on statrs' CDF: accurate for any EDF,
    /// including the 10⁵ and more of long records.
    Newton,
    /// statrs' `inverse_cdf` as it is: a fixed, short bisection, inaccurate at very large EDF.
    Statrs,
}

/// The q-quantile χ²(q ; ν) of the χ² distribution with `nu` degrees of freedom.
///
/// Returns `None` when `nu` is not a valid number of degrees of freedom; with
/// [`Chi2Inversion::Newton`] also when `nu` is infinite or the result is not a positive finite
/// number. [`Chi2Inversion::Statrs`] returns statrs' value as it is.
///
/// ```
/// use fdavar::allan::edf::{chi2_quantile, Chi2Inversion};
/// // χ²(0.5; 100) = 99.33413 (scipy.stats.chi2.ppf)
/// let q = chi2_quantile(0.5, 100.0, Chi2Inversion::Newton).unwrap();
/// assert!((q - 99.334_129_235_988_46).abs() < 1e-6);
/// ```
pub fn chi2_quantile(q: f64, nu: f64, inversion: Chi2Inversion) -> Option<f64> {
    let dist = ChiSquared::new(nu).ok()?;
    match inversion {
        Chi2Inversion::Statrs => Some(dist.inverse_cdf(q)),
        Chi2Inversion::Newton if nu.is_finite() => newton_quantile(&dist, q, nu),
        Chi2Inversion::Newton => None,
    }
}

/// The two quantiles that bound a two-sided interval: `(χ²(p_low ; ν), χ²(1 − p_low ; ν))`.
pub fn chi2_tail_quantiles(p_low: f64, nu: f64, inversion: Chi2Inversion) -> Option<(f64, f64)> {
    Some((
        chi2_quantile(p_low, nu, inversion)?,
        chi2_quantile(1.0 - p_low, nu, inversion)?,
    ))
}

/// χ² confidence interval of a variance estimate with `edf` degrees of freedom.
///
/// Returns `(low, high)` for the variance (take square roots for deviations). `confidence` is the
/// two-sided level, e.g. [`ONE_SIGMA`]. Returns `None` when `edf` is not positive and finite or
/// `confidence` is outside (0, 1). The quantiles are [`Chi2Inversion::Newton`]'s; see
/// [`chi2_interval_with`] for the other.
///
/// # Formula
/// ```text
/// low = edf·σ² / χ²(1 − p/2 ; edf),   high = edf·σ² / χ²(p/2 ; edf),   p = 1 − confidence
/// ```
/// where χ²(q ; ν) is the q-quantile of the χ² distribution with ν degrees of freedom.
///
/// # References
/// Riley W. J., NIST SP 1065, 2008, §5.3.3, Eq. (45).
///
/// ```
/// use fdavar::allan::edf::{chi2_interval, ONE_SIGMA};
/// let (lo, hi) = chi2_interval(1.0, 10.0, ONE_SIGMA).unwrap();
/// // χ²(0.8413; 10) = 14.32551, χ²(0.1587; 10) = 5.68062 (scipy.stats.chi2.ppf)
/// assert!((lo - 10.0 / 14.32551).abs() < 1e-5 && (hi - 10.0 / 5.68062).abs() < 1e-5);
/// ```
pub fn chi2_interval(avar: f64, edf: f64, confidence: f64) -> Option<(f64, f64)> {
    chi2_interval_with(avar, edf, confidence, Chi2Inversion::Newton)
}

/// [`chi2_interval`] with the quantiles of `inversion`.
///
/// Returns `None` when `edf` is not positive, `confidence` is outside (0, 1) or a quantile is
/// undefined ([`chi2_quantile`]).
pub fn chi2_interval_with(
    avar: f64,
    edf: f64,
    confidence: f64,
    inversion: Chi2Inversion,
) -> Option<(f64, f64)> {
    if !(edf > 0.0 && confidence > 0.0 && confidence < 1.0) {
        return None;
    }
    let p = (1.0 - confidence) / 2.0;
    let (lo_q, hi_q) = chi2_tail_quantiles(p, edf, inversion)?;
    Some((edf * avar / hi_q, edf * avar / lo_q))
}

/// The q-quantile of `dist` = χ²(ν), ν finite: Wilson–Hilferty start, polished by Newton steps.
fn newton_quantile(dist: &ChiSquared, q: f64, nu: f64) -> Option<f64> {
    let z = standard_normal_quantile(q);
    let k = 2.0 / (9.0 * nu);
    let mut x = (nu * (1.0 - k + z * k.sqrt()).powi(3))
        .max(nu * 1e-3)
        .max(1e-300);
    for _ in 0..50 {
        let step = (dist.cdf(x) - q) / dist.pdf(x);
        if !step.is_finite() {
            break;
        }
        let next = if x - step > 0.0 { x - step } else { x / 2.0 };
        let done = (next - x).abs() <= 1e-13 * x;
        x = next;
        if done {
            break;
        }
    }
    (x.is_finite() && x > 0.0).then_some(x)
}

/// The standard normal quantile (Acklam's rational approximation, relative error < 1.2e-9).
fn standard_normal_quantile(p: f64) -> f64 {
    use statrs::distribution::Normal;
    Normal::new(0.0, 1.0).map_or(0.0, |n| n.inverse_cdf(p))
}

/// Blocks of the record whose means give the standard error of [`white_fourth_cumulant`]'s
/// estimate (the terms are serially correlated, so the error is read off the data).
pub const KURTOSIS_BLOCKS: usize = 64;

/// How many standard errors the estimate of [`white_fourth_cumulant`] must exceed 0 by before it
/// is reported.
///
/// Why a significance test and not the raw estimate: on Gaussian noise the estimate scatters
/// around zero, and the EDF of Gaussian noise should stay Greenhall's and NIST's to the bit.
/// Why three and not five: the standard error is read off the data, and spikes inflate it as
/// much as the estimate, so the test's power grows only as the square root of their number. The
/// MTi-G record of [`white_fourth_cumulant`] has 173 differences beyond 5σ and passes at 4.0
/// standard errors. On Gaussian noise (numpy's generator, the same statistic: 500 records of
/// 12 000 samples, 200 of 360 000) 2 and 0 records passed; one that does gets a κ₄ of about
/// three standard errors, which widens its shortest τ's interval by about a tenth.
pub const KURTOSIS_SIGMAS: f64 = 3.0;

/// The fourth cumulant κ₄ of the white rate noise in `rate` (sampled at a fixed period, NaN for
/// a missing sample), or 0 when it is not measurably above zero (Gaussian noise, or lighter
/// tails: a line, a low-pass) or when the record is quantized coarser than its noise
/// ([`LATTICE_STEPS`]).
///
/// Why: the EDFs of Greenhall and NIST SP 1065 hold for Gaussian noise. Real IMUs also emit
/// isolated spikes (a bus glitch, a shock): in the Allan variance they are only more white noise,
/// but an estimate's scatter grows with the noise's fourth cumulant
/// ([`edf_with_fourth_cumulant`]), and the z of a Gaussian EDF then calls every span that holds a
/// few more or fewer spikes a failure. Measured on a real XSens MTi-G gyro (imudata `cont.imu1`,
/// 5·10⁵ samples at 100 Hz): excess kurtosis of the differences 58, with the spans' short-τ
/// Allan variance scattered by ±7 % where their median level varies by ±2 %.
///
/// # Formula
/// ```text
/// dᵢ = yᵢ₊₁ − yᵢ,   uᵢ = dᵢ⁴ − 3·dᵢ²·dᵢ₊₂²,   κ₄ = mean(u) / 2   if mean(u) > KURTOSIS_SIGMAS · SE
/// ```
/// For independent y, dᵢ and dᵢ₊₂ share no sample, so E dᵢ²dᵢ₊₂² = (E d²)² and E u is the fourth
/// cumulant of d, twice that of y. Why the neighbour and not the record's E d²: a level that
/// changes in time (a noise burst, a warm-up) raises the record's kurtosis, but dᵢ and dᵢ₊₂ see
/// the same level, so the pair cancels it: non-stationarity stays the span check's to show.
/// Correlated Gaussian noise (a line, a low-pass) gives E u = −6ρ²(E d²)² ≤ 0, ρ the correlation
/// of dᵢ and dᵢ₊₂: never a false κ₄. SE is the
/// standard error from the means of [`KURTOSIS_BLOCKS`] consecutive blocks.
///
/// ```
/// use fdavar::allan::edf::white_fourth_cumulant;
/// // A regular zig-zag is lighter-tailed than Gaussian: nothing to report.
/// let y: Vec<f64> = (0..5000).map(|i| if i % 2 == 0 { 1.0 } else { -1.0 }).collect();
/// assert_eq!(white_fourth_cumulant(&y), 0.0);
/// ```
pub fn white_fourth_cumulant(rate: &[f64]) -> f64 {
    let terms = rate.len().saturating_sub(3);
    if terms < 16 * KURTOSIS_BLOCKS {
        return 0.0;
    }
    let (mut total, mut count, mut block_means) = (0.0, 0usize, Vec::with_capacity(KURTOSIS_BLOCKS));
    let mut lattice = Lattice { step: f64::INFINITY, sum: 0.0, count: 0 };
    for b in 0..KURTOSIS_BLOCKS {
        let (start, end) = (b * terms / KURTOSIS_BLOCKS, (b + 1) * terms / KURTOSIS_BLOCKS);
        let at = |k: usize| &rate[start + k..end + k];
        let (mut sum, mut n) = (0.0, 0usize);
        // One pass, without branches: a missing sample makes u NaN and is counted out.
        for (((&y0, &y1), &y2), &y3) in at(0).iter().zip(at(1)).zip(at(2)).zip(at(3)) {
            let (d, d2) = (y1 - y0, y3 - y2);
            let (d_sq, d2_sq) = (d * d, d2 * d2);
            let u = d_sq * (d_sq - 3.0 * d2_sq);
            let valid = u.is_finite();
            (sum, n) = (sum + if valid { u } else { 0.0 }, n + usize::from(valid));
            lattice.add(d);
        }
        if n > 0 {
            block_means.push(sum / n as f64);
        }
        (total, count) = (total + sum, count + n);
    }
    let blocks = block_means.len();
    if blocks < 2 || count == 0 || lattice.is_coarse() {
        return 0.0;
    }
    let mean = total / count as f64;
    let spread = block_means.iter().map(|b| (b - mean).powi(2)).sum::<f64>() / (blocks - 1) as f64;
    let standard_error = (spread / blocks as f64).sqrt();
    if mean > KURTOSIS_SIGMAS * standard_error {
        mean / 2.0
    } else {
        0.0
    }
}

/// Output steps per typical rate difference below which [`white_fourth_cumulant`] reads a record
/// as quantized rather than spiky.
pub const LATTICE_STEPS: f64 = 2.0;

/// What tells whether the differences of a record sit on an output lattice coarser than its
/// noise: the smallest non-zero |d| (the output step) and the mean |d|.
///
/// Why: where the noise does not dither the quantizer, the differences are mostly 0 and now and
/// then one step, which is heavy-tailed but not independent spikes: the rounding error follows the
/// input, and `quantization` describes it. Measured: a 1e-4 rad angle quantizer under 0.04 step of
/// noise per sample (tests/quantization_dither.rs) read as excess kurtosis, and the widened fit
/// put q 16 % high. A fine lattice (the ADIS16405's gyro: 9–11 steps per σ of the differences)
/// changes the kurtosis by Sheppard's −h⁴/120, nothing to widen for.
struct Lattice {
    step: f64,
    sum: f64,
    count: usize,
}

impl Lattice {
    fn add(&mut self, d: f64) {
        let size = d.abs();
        let valid = size.is_finite();
        self.step = self.step.min(if size > 0.0 && valid { size } else { f64::INFINITY });
        (self.sum, self.count) = (self.sum + if valid { size } else { 0.0 }, self.count + usize::from(valid));
    }

    /// The typical |d| (mean |d|·√(π/2), the σ of Gaussian d) under [`LATTICE_STEPS`] steps.
    fn is_coarse(&self) -> bool {
        self.count > 0 && self.sum / self.count as f64 * (std::f64::consts::PI / 2.0).sqrt() < LATTICE_STEPS * self.step
    }
}

/// The EDF of an overlapping Allan variance estimate `avar` at factor `m` over `terms` terms,
/// whose Gaussian EDF is `edf`, when its white rate noise has the fourth cumulant `kappa4`
/// ([`white_fourth_cumulant`]); `edf` itself when `kappa4` is 0.
///
/// # Formula
/// The estimate is a quadratic form σ̂² = yᵀAy of the rate samples with A_jj = 1/(m·T) (each
/// sample in 2m of the T terms, each term (Σ±y)²/(2m²T)). For independent samples with fourth
/// cumulant κ₄, Var(yᵀAy) = 2·tr((AΣ)²) + κ₄·Σ A_jj² exactly, so
/// ```text
/// Var(σ̂²) = 2σ⁴/EDF + κ₄/(m²·T)
/// EDF'    = 2σ⁴/Var(σ̂²) = EDF / (1 + κ₄·EDF / (2·m²·T·σ⁴))
/// ```
/// For white noise at m = 1 (EDF ≈ 2T/3) the variance grows by 1 + κ/3, κ the samples' excess
/// kurtosis; the term fades as 1/m because averages are closer to Gaussian. Checked by simulation
/// in this module's tests (independent samples with spikes, m = 1 … 64).
///
/// # References
/// Searle S. R., "Linear Models", Wiley, 1971, §2.5 (variance of a quadratic form in non-normal
/// variables); Greenhall & Riley, PTTI 2003 (the Gaussian EDF).
///
/// ```
/// use fdavar::allan::edf::edf_with_fourth_cumulant;
/// assert_eq!(edf_with_fourth_cumulant(600.0, 1.0, 1, 900, 0.0), 600.0);
/// // Excess kurtosis 3 at m = 1: the variance of the estimate doubles.
/// assert!((edf_with_fourth_cumulant(600.0, 1.0, 1, 900, 3.0) - 300.0).abs() < 1e-9);
/// // Never below one degree of freedom.
/// assert_eq!(edf_with_fourth_cumulant(600.0, 1e-300, 1, 900, 3.0), 1.0);
/// ```
pub fn edf_with_fourth_cumulant(edf: f64, avar: f64, m: usize, terms: usize, kappa4: f64) -> f64 {
    if !(kappa4 > 0.0 && avar > 0.0) || terms == 0 || m == 0 {
        return edf;
    }
    let m = m as f64;
    let widened = edf / (1.0 + kappa4 * edf / (2.0 * m * m * terms as f64 * avar * avar));
    // An estimate is worth at least one degree of freedom (as the Gaussian EDFs), also where
    // a tiny `avar` or a huge κ₄ would drive the quotient to 0 or NaN.
    if widened.is_finite() { widened.max(edf.min(1.0)) } else { edf.min(1.0) }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OADEV: VarianceShape = VarianceShape {
        d: 2,
        overlapping: true,
        modified: false,
    };

    /// Independent samples of unit Gaussian noise with a spike of `spike` σ in a share `p` of
    /// them; with the variance and fourth cumulant of their distribution.
    fn spiky(n: usize, p: f64, spike: f64, rng: &mut rand_chacha::ChaCha8Rng) -> Vec<f64> {
        use rand::Rng;
        use rand_distr::{Distribution, StandardNormal};
        (0..n)
            .map(|_| {
                let g: f64 = StandardNormal.sample(rng);
                if rng.random::<f64>() < p { g * spike } else { g }
            })
            .collect()
    }

    fn spiky_moments(p: f64, spike: f64) -> (f64, f64) {
        let var = 1.0 - p + p * spike * spike;
        let m4 = 3.0 * (1.0 - p + p * spike.powi(4));
        (var, m4 - 3.0 * var * var)
    }

    #[test]
    fn the_fourth_cumulant_gives_the_scatter_of_allan_estimates_of_spiky_noise() {
        use crate::model::measure::{edf_oavar, NoiseClass};
        use rand::SeedableRng;
        let (n, records, p, spike) = (4096, 1500, 5e-3, 8.0);
        let (var, kappa4) = spiky_moments(p, spike);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let factors = [1usize, 4, 16, 64];
        let mut estimates = vec![Vec::with_capacity(records); factors.len()];
        let mut layout = Vec::new();
        for _ in 0..records {
            let y = spiky(n, p, spike, &mut rng);
            let points = crate::allan::oavar_rate(&y, 1.0, &factors);
            for (e, q) in estimates.iter_mut().zip(&points) {
                e.push(q.avar);
            }
            layout = points.iter().map(|q| (q.m, q.terms)).collect();
        }
        for (e, &(m, terms)) in estimates.iter().zip(&layout) {
            let mean = e.iter().sum::<f64>() / e.len() as f64;
            let scatter = e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (e.len() - 1) as f64;
            let avar = var / m as f64;
            let gaussian = edf_oavar(NoiseClass::WhiteFm, terms + 2 * m, m);
            let widened = edf_with_fourth_cumulant(gaussian, avar, m, terms, kappa4);
            let ratio = scatter / (2.0 * avar * avar / widened);
            assert!((0.85..1.18).contains(&ratio), "m {m}: simulated / predicted variance {ratio}");
            // The Gaussian EDF alone understates the scatter, most at the shortest τ.
            let understated = scatter / (2.0 * avar * avar / gaussian);
            assert!(understated > if m == 1 { 8.0 } else { 1.3 }, "m {m}: {understated}");
        }
    }

    #[test]
    fn the_fourth_cumulant_is_measured_from_the_samples() {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        for (p, spike) in [(5e-3, 8.0), (1e-3, 20.0), (0.05, 3.0)] {
            let (mut found, mut drawn) = (0.0, 0.0);
            for _ in 0..8 {
                let y = spiky(200_000, p, spike, &mut rng);
                let k = white_fourth_cumulant(&y);
                assert!(k > 0.0, "{p} {spike}");
                // Against the fourth cumulant of the samples drawn: a few 20σ spikes move the
                // population's by a quarter from record to record.
                let n = y.len() as f64;
                let var = y.iter().map(|v| v * v).sum::<f64>() / n;
                let m4 = y.iter().map(|v| v.powi(4)).sum::<f64>() / n;
                (found, drawn) = (found + k, drawn + m4 - 3.0 * var * var);
            }
            assert!((found / drawn - 1.0).abs() < 0.1, "{p} {spike}: {found} vs {drawn}");
        }
    }

    #[test]
    fn gaussian_noise_and_level_changes_report_no_fourth_cumulant() {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut reported = 0;
        for _ in 0..200 {
            let mut y = spiky(20_000, 0.0, 1.0, &mut rng);
            // A burst: four times the level over a fifth of the record.
            y[8000..12_000].iter_mut().for_each(|v| *v *= 4.0);
            reported += usize::from(white_fourth_cumulant(&y) > 0.0);
        }
        assert_eq!(reported, 0);
        // Spikes as rare as one sample in 500 are found.
        let y = spiky(20_000, 2e-3, 20.0, &mut rng);
        assert!(white_fourth_cumulant(&y) > 0.0);
    }

    #[test]
    fn quantiles_match_tables() {
        // Reference quantiles from scipy.stats.chi2.ppf (SciPy 1.x, cephes).
        // ν = 1: χ² = z², so P(χ² ≤ 1) = P(|z| ≤ 1) = erf(1/√2) exactly.
        let q = chi2_quantile(ONE_SIGMA, 1.0, Chi2Inversion::Newton).unwrap();
        assert!((q - 1.0).abs() < 1e-9, "{q}");
        let p = (1.0 - ONE_SIGMA) / 2.0;
        for (q, nu, want) in [
            (p, 10.0, 5.680_617_711_186_441),
            (1.0 - p, 10.0, 14.325_506_344_521_887),
            (0.5, 100.0, 99.334_129_235_988_46),
            (p, 5e5, 499_000.000_666_726),
        ] {
            let got = chi2_quantile(q, nu, Chi2Inversion::Newton).unwrap();
            assert!(
                (got / want - 1.0).abs() < 1e-8,
                "q={q} ν={nu}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn invalid_inputs_give_none() {
        assert!(greenhall_edf(-2, VarianceShape { d: 1, ..OADEV }, 1, 100).is_none());
        assert!(greenhall_edf(-3, OADEV, 1, 100).is_none());
        assert!(greenhall_edf(0, OADEV, 50, 100).is_none());
        // The shortest record that has one term still has an EDF (M = 1).
        let adev = VarianceShape { overlapping: false, ..OADEV };
        for alpha in -2..=2 {
            let e = greenhall_edf(alpha, adev, 10, 21).unwrap();
            // One squared Gaussian second difference is σ²·χ²₁, whatever the noise: EDF 1.
            assert!((e - 1.0).abs() < 0.05, "α={alpha}: {e}");
        }
        assert!(chi2_interval(1.0, 0.0, ONE_SIGMA).is_none());
        assert!(chi2_interval(1.0, 3.0, 1.0).is_none());
    }

    /// Exact EDF of the overlapping AVAR of discrete white FM: M / Σ_k ρ(k)² with the terms'
    /// autocorrelation ρ(k) = (2m − 3|k|)/(2m) for |k| ≤ m, −(2m − |k|)/(2m) for m ≤ |k| ≤ 2m.
    fn exact_white_fm_oadev_edf(n: usize, m: usize) -> f64 {
        let big_m = (n - 2 * m) as f64;
        let mf = m as f64;
        let rho = |k: f64| {
            if k <= mf {
                (2.0 * mf - 3.0 * k) / (2.0 * mf)
            } else {
                -(2.0 * mf - k) / (2.0 * mf)
            }
        };
        let s: f64 = (1..2 * m)
            .map(|k| 2.0 * (1.0 - k as f64 / big_m) * rho(k as f64).powi(2))
            .sum();
        big_m / (1.0 + s)
    }

    #[test]
    fn white_fm_oadev_edf_matches_exact_for_large_m() {
        // m·(d+1) > J_max: Greenhall's m' = ∞ models the sampled random walk exactly.
        for m in [40, 100, 1000] {
            let g = greenhall_edf(0, OADEV, m, 100_001).unwrap();
            let exact = exact_white_fm_oadev_edf(100_001, m);
            assert!((g / exact - 1.0).abs() < 1e-3, "m={m}: {g} vs {exact}");
        }
    }

    #[test]
    fn white_fm_oadev_edf_small_m_is_stable32s() {
        // m·(d+1) ≤ J_max: the algorithm (and Stable32) uses m' = m, a phase averaged over τ0,
        // which gives a smaller EDF than the sampled random walk: 1368.0 vs ≈ 1479 at m = 10.
        let g = greenhall_edf(0, OADEV, 10, 10_001).unwrap();
        assert!((g - 1367.955).abs() < 1e-2, "{g}");
        assert!((exact_white_fm_oadev_edf(10_001, 10) / 1478.7 - 1.0).abs() < 1e-3);
    }
}

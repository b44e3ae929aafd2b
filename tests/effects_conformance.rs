//! Effect conformance (STYLE.md tests §4): every entry of the registry, simulated with a fixed seed,
//! must show the Allan signature or the time-domain form it claims.
//!
//! Spectral effects go through one shared check, [`check_effect`]: the effect is simulated on top of
//! a known white background, the overlapping Allan variance of the record is computed on an octave
//! grid with the brute-force oracle, and at ≥ 90 % of the τ points the measurement must lie inside
//! the 99 % χ² interval of the predicted σ²(τ) = background + `avar(τ)`. The check also demands that
//! the effect be *visible*: at two τ points or more the background alone must lie outside the
//! interval, so an effect that simulated nothing would fail. Time-domain effects are checked on their
//! simulated form (step time and size, burst variance ratio, regression coefficient).
//!
//! EDF: the simple closed forms for the overlapping Allan variance quoted in NIST SP 1065 §5.3.3
//! (Howe, Allan & Barnes 1981), the noise type taken from the local log-log slope of the predicted
//! σ²(τ) at that τ.

use fdavar::allan::naive::{oavar, phase_from_rate};
use fdavar::model::effects::{
    find, Domain, Effect, EffectKind, Explanation, Param, SimContext, SimStage, REGISTRY,
};
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor, Normal};

/// A spectral case: the effect, its white background, the record and the first averaging factor.
struct Case {
    effect: Box<dyn Effect>,
    background_n: f64,
    dt: f64,
    len: usize,
    m_min: usize,
    seed: u64,
}

/// One τ point of a conformance check.
#[derive(Debug)]
struct Point {
    tau: f64,
    measured: f64,
    predicted: f64,
    low: f64,
    high: f64,
    background_outside: bool,
}

impl Point {
    fn inside(&self) -> bool {
        (self.low..=self.high).contains(&self.predicted)
    }
}

/// The outcome of [`check_effect`]: every point and the two verdicts.
#[derive(Debug)]
struct Report {
    id: &'static str,
    points: Vec<Point>,
}

impl Report {
    fn coverage(&self) -> f64 {
        self.points.iter().filter(|p| p.inside()).count() as f64 / self.points.len() as f64
    }
    fn visible_points(&self) -> usize {
        self.points.iter().filter(|p| p.background_outside).count()
    }
    fn passes(&self) -> bool {
        self.coverage() >= 0.9 && self.visible_points() >= 2
    }
}

/// EDF of the overlapping Allan variance for `n` phase points at averaging factor `m`, for the
/// power-law noise whose σ²(τ) slope is nearest `slope` (NIST SP 1065 §5.3.3).
fn edf(n: usize, m: usize, slope: f64) -> f64 {
    let (n, m) = (n as f64, m as f64);
    if slope < -1.5 {
        // white PM
        (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m))
    } else if slope < -0.5 {
        // white FM
        (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * 4.0 * m * m / (4.0 * m * m + 5.0)
    } else if slope < 0.5 {
        // flicker FM (m = 1 with the squared numerator: the unsquared form quoted in some tables
        // gives an EDF below 1 for any record length)
        if m < 2.0 {
            2.0 * (n - 2.0).powi(2) / (2.3 * n - 4.9)
        } else {
            5.0 * n * n / (4.0 * m * (n + 3.0 * m))
        }
    } else {
        // random walk FM (also used for a ramp, whose estimate has no scatter at all)
        (n - 2.0) / m * ((n - 1.0).powi(2) - 3.0 * m * (n - 1.0) + 4.0 * m * m) / (n - 3.0).powi(2)
    }
}

/// The 99 % χ² interval of the true σ² given a measurement with `edf` degrees of freedom.
fn interval(measured: f64, edf: f64) -> (f64, f64) {
    let chi = ChiSquared::new(edf).expect("edf > 0");
    (
        measured * edf / chi.inverse_cdf(0.995),
        measured * edf / chi.inverse_cdf(0.005),
    )
}

fn context(dt: f64) -> SimContext<'static> {
    SimContext {
        dt,
        white_sigma: 0.0,
        temperature_c: None,
        accel: None,
    }
}

/// Simulates `effects` on one axis (additive ones first, then output stages) with a seeded stream
/// per effect.
fn simulate(effects: &[&dyn Effect], ctx: &SimContext<'_>, len: usize, seed: u64) -> Vec<f64> {
    let mut out = vec![0.0; len];
    for stage in [SimStage::Additive, SimStage::Output] {
        for (i, e) in effects.iter().enumerate() {
            if e.kind().sim_stage() == stage {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream(i as u64);
                e.simulate(ctx, &mut rng, &mut out);
            }
        }
    }
    out
}

/// Local log-log slope of `f` at `tau`.
fn slope(f: &dyn Fn(f64) -> f64, tau: f64) -> f64 {
    let h = 1.05;
    (f(tau * h) / f(tau / h)).ln() / (h * h).ln()
}

/// The shared conformance check of a spectral effect (see the module doc).
fn check_effect(case: &Case) -> Report {
    let effect = case.effect.as_ref();
    let white = find("white").unwrap().build(&[case.background_n]).unwrap();
    let y = simulate(
        &[white.as_ref(), effect],
        &context(case.dt),
        case.len,
        case.seed,
    );
    let x = phase_from_rate(&y, case.dt);
    let background = |tau: f64| white.avar(tau).unwrap();
    let predicted = |tau: f64| background(tau) + effect.avar(tau).unwrap();
    let mut points = Vec::new();
    let mut m = case.m_min;
    while 3 * m <= case.len {
        let tau = m as f64 * case.dt;
        let measured = oavar(&x, case.dt, m).unwrap();
        let (low, high) = interval(measured, edf(x.len(), m, slope(&predicted, tau)));
        let b = background(tau);
        points.push(Point {
            tau,
            measured,
            predicted: predicted(tau),
            low,
            high,
            background_outside: !(low..=high).contains(&b),
        });
        m *= 2;
    }
    Report {
        id: effect.kind().id(),
        points,
    }
}

fn build(id: &str, values: &[f64]) -> Box<dyn Effect> {
    find(id)
        .unwrap_or_else(|| panic!("{id} not in REGISTRY"))
        .build(values)
        .unwrap()
}

/// The spectral case of a registry kind, with parameters a MEMS gyro at 100 Hz could have and a
/// background chosen so that the effect dominates somewhere on the grid.
fn spectral_case(kind: &dyn EffectKind, seed: u64) -> Case {
    let (values, background_n, len, m_min): (&[f64], f64, usize, usize) = match kind.id() {
        // Δ = q·√12/τ0 = 1e-2 rad/s, dithered by a background of σ = 1e-2 rad/s per sample.
        "quantization" => (&[1e-2 * 0.01 / 3.4641016151377544], 1e-3, 1 << 16, 1),
        "white" => (&[1e-3], 5e-4, 1 << 16, 1),
        // Flicker departs from its continuous floor below m ≈ 8 (see BiasInstability).
        "bias_instability" => (&[1e-4], 1e-4, 1 << 17, 8),
        "random_walk" => (&[1e-3], 1e-3, 1 << 16, 1),
        "sinusoid" => (&[1e-2, 0.5], 1e-3, 1 << 16, 1),
        "vibration" => (&[1e-2, 0.5], 1e-3, 1 << 16, 1),
        "gauss_markov" => (&[1e-2, 5.0], 1e-3, 1 << 16, 1),
        // T = 8 ms against τ0 = 10 ms: σ²(τ0) is 45 % below N²/τ0, the deficit visible to m ≈ 4.
        "bandwidth" => (&[1e-2, 20.0], 1e-3, 1 << 16, 1),
        other => panic!("no spectral conformance case for '{other}': add one"),
    };
    Case {
        effect: build(kind.id(), values),
        background_n,
        dt: 0.01,
        len,
        m_min,
        seed,
    }
}

fn describe(r: &Report) -> String {
    let mut s = format!(
        "{}: coverage {:.2}, visible at {} points\n",
        r.id,
        r.coverage(),
        r.visible_points()
    );
    for p in &r.points {
        s += &format!(
            "  tau {:>9.3} measured {:.4e} predicted {:.4e} in [{:.4e}, {:.4e}] {}\n",
            p.tau,
            p.measured,
            p.predicted,
            p.low,
            p.high,
            if p.inside() { "" } else { "OUTSIDE" }
        );
    }
    s
}

#[test]
fn every_spectral_effect_shows_its_allan_signature() {
    for kind in REGISTRY.iter().filter(|k| k.domain() == Domain::Spectral) {
        let report = check_effect(&spectral_case(*kind, 2016));
        eprintln!("{}", describe(&report));
        assert!(report.passes(), "{}", describe(&report));
    }
}

/// A broken effect for testing the check: it claims `claim`× the signature of `inner`, and
/// simulates `inner` only when `simulates` is true.
#[derive(Debug)]
struct Broken {
    inner: Box<dyn Effect>,
    claim: f64,
    simulates: bool,
}

impl Effect for Broken {
    fn kind(&self) -> &'static dyn EffectKind {
        self.inner.kind()
    }
    fn params(&self) -> Vec<Param> {
        self.inner.params()
    }
    fn avar(&self, tau: f64) -> Option<f64> {
        self.inner.avar(tau).map(|v| self.claim * v)
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        if self.simulates {
            self.inner.simulate(ctx, rng, out)
        }
    }
    fn explain(&self) -> Explanation {
        self.inner.explain()
    }
}

/// The spectral case of `id`, with its effect replaced by a broken copy.
fn broken_case(id: &str, claim: f64, simulates: bool) -> Case {
    let case = spectral_case(find(id).unwrap(), 7);
    Case {
        effect: Box::new(Broken {
            inner: case.effect,
            claim,
            simulates,
        }),
        ..case
    }
}

#[test]
fn the_check_rejects_a_wrong_signature() {
    // White noise that claims 30 % more Allan variance than it makes.
    let report = check_effect(&broken_case("white", 1.3, true));
    assert!(!report.passes(), "{}", describe(&report));
}

#[test]
fn the_check_rejects_an_effect_that_does_nothing() {
    // Claims the signature of a random walk but simulates nothing.
    let report = check_effect(&broken_case("random_walk", 1.0, false));
    assert!(!report.passes(), "{}", describe(&report));
}

/// Mean and variance of a slice.
fn mean_var(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var)
}

/// Least-squares slope of y on x with its standard error.
fn regression(x: &[f64], y: &[f64]) -> (f64, f64) {
    let (mx, _) = mean_var(x);
    let (my, _) = mean_var(y);
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let beta = sxy / sxx;
    let resid: f64 = x
        .iter()
        .zip(y)
        .map(|(a, b)| (b - my - beta * (a - mx)).powi(2))
        .sum();
    let se = (resid / (x.len() as f64 - 2.0) / sxx).sqrt();
    (beta, se)
}

/// |z| bound for a two-sided 99.9 % test.
fn z999() -> f64 {
    Normal::new(0.0, 1.0).unwrap().inverse_cdf(0.9995)
}

/// Checks a time-domain effect on its simulated form; panics with the reason when it fails.
fn check_time_domain(kind: &dyn EffectKind, seed: u64) {
    let dt: f64 = 0.01;
    let len = 20_000;
    let white_n = 1e-3;
    let white_sigma = white_n / dt.sqrt();
    let white = build("white", &[white_n]);
    let params = |e: &dyn Effect| -> Vec<f64> { e.params().iter().map(|p| p.value).collect() };
    match kind.id() {
        "bias_step" => {
            let step = build("bias_step", &[50.0, 0.02]);
            // Exact form on zeros: nothing before sample 5000, the full size from it on.
            let y = simulate(&[step.as_ref()], &context(dt), len, seed);
            assert!(y[..5000].iter().all(|&v| v == 0.0));
            assert!(y[5000..].iter().all(|&v| v == 0.02));
            // In noise: the mean difference is the size within its standard error.
            let y = simulate(&[white.as_ref(), step.as_ref()], &context(dt), len, seed);
            let (m0, v0) = mean_var(&y[..5000]);
            let (m1, v1) = mean_var(&y[5000..]);
            let se = (v0 / 5000.0 + v1 / 15000.0).sqrt();
            assert!(((m1 - m0) - 0.02).abs() < z999() * se, "step {}", m1 - m0);
        }
        "noise_burst" => {
            let burst = build("noise_burst", &[40.0, 120.0, 3.0]);
            let ctx = SimContext {
                white_sigma,
                ..context(dt)
            };
            let y = simulate(&[white.as_ref(), burst.as_ref()], &ctx, len, seed);
            let (_, inside) = mean_var(&y[4000..12000]);
            let outside: Vec<f64> = y[..4000].iter().chain(&y[12000..]).copied().collect();
            let (_, out_var) = mean_var(&outside);
            let f = FisherSnedecor::new(7999.0, outside.len() as f64 - 1.0).unwrap();
            let ratio = inside / out_var / 9.0;
            assert!(
                (f.inverse_cdf(0.0005)..=f.inverse_cdf(0.9995)).contains(&ratio),
                "variance ratio / factor² = {ratio}"
            );
            assert!((out_var / (white_sigma * white_sigma) - 1.0).abs() < 0.05);
        }
        "temperature" => {
            let effect = build("temperature", &[2e-4]);
            let temps: Vec<f64> = (0..len)
                .map(|n| 40.0 - 15.0 * (-(n as f64) * dt / 60.0).exp())
                .collect();
            let ctx = SimContext {
                temperature_c: Some(&temps),
                ..context(dt)
            };
            let y = simulate(&[white.as_ref(), effect.as_ref()], &ctx, len, seed);
            let (beta, se) = regression(&temps, &y);
            assert!(
                (beta - params(effect.as_ref())[0]).abs() < z999() * se,
                "{beta} ± {se}"
            );
            assert!(y[0].abs() < 5.0 * white_sigma, "zero at the first sample");
        }
        "g_sensitivity" => {
            let effect = build("g_sensitivity", &[1.0, 3e-3]);
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xacce1);
            let ax: Vec<f64> = (0..len).map(|_| rng.random::<f64>() - 0.5).collect();
            let ay: Vec<f64> = (0..len)
                .map(|n| 0.8 * (n as f64 * dt * 2.0 * 3.7).sin())
                .collect();
            let az = vec![9.80665; len];
            let ctx = SimContext {
                accel: Some([&ax, &ay, &az]),
                ..context(dt)
            };
            let y = simulate(&[white.as_ref(), effect.as_ref()], &ctx, len, seed);
            let (beta, se) = regression(&ay, &y);
            assert!(
                (beta - 3e-3).abs() < z999() * se,
                "on the source: {beta} ± {se}"
            );
            let (beta_x, se_x) = regression(&ax, &y);
            assert!(
                beta_x.abs() < z999() * se_x,
                "not on another axis: {beta_x} ± {se_x}"
            );
        }
        "ramp" => {
            let effect = build("ramp", &[2e-4]);
            // Exact form on zeros: r·n·τ0.
            let y = simulate(&[effect.as_ref()], &context(dt), len, seed);
            assert!(y.iter().enumerate().all(|(n, v)| (v - 2e-4 * n as f64 * dt).abs() < 1e-15));
            // In noise: the slope on time is r within its standard error.
            let y = simulate(&[white.as_ref(), effect.as_ref()], &context(dt), len, seed);
            let t: Vec<f64> = (0..len).map(|n| n as f64 * dt).collect();
            let (beta, se) = regression(&t, &y);
            assert!((beta - 2e-4).abs() < z999() * se, "{beta} ± {se}");
        }
        other => panic!("no time-domain conformance case for '{other}': add one"),
    }
}

#[test]
fn every_time_domain_effect_shows_its_form() {
    for kind in REGISTRY.iter().filter(|k| k.domain() == Domain::TimeDomain) {
        check_time_domain(*kind, 2016);
    }
}

#[test]
fn registry_order_and_names_are_the_contract() {
    let ids: Vec<_> = REGISTRY.iter().map(|k| k.id()).collect();
    assert_eq!(
        ids,
        [
            "quantization",
            "white",
            "bias_instability",
            "random_walk",
            "ramp",
            "sinusoid",
            "bandwidth",
            "gauss_markov",
            "bias_step",
            "noise_burst",
            "temperature",
            "g_sensitivity",
            "vibration"
        ]
    );
    let aliases: Vec<_> = REGISTRY.iter().filter_map(|k| k.alias()).collect();
    assert_eq!(aliases, ["Q", "N", "B", "K", "R"]);
    for kind in REGISTRY {
        assert!(std::ptr::eq(
            find(kind.id()).unwrap() as *const dyn EffectKind as *const u8,
            *kind as *const dyn EffectKind as *const u8
        ));
    }
}

#[test]
fn every_parameter_rejects_nan_and_out_of_bounds_by_name() {
    for kind in REGISTRY {
        let schema = kind.schema();
        let good: Vec<f64> = schema
            .iter()
            .map(|s| s.bounds.0.max(0.0).min(s.bounds.1))
            .collect();
        for (i, spec) in schema.iter().enumerate() {
            for bad in [f64::NAN, f64::INFINITY, spec.bounds.1 * 2.0 + 1.0] {
                let mut values = good.clone();
                values[i] = bad;
                let err = kind.build(&values).unwrap_err().to_string();
                assert!(err.contains(spec.name), "{}: {err}", kind.id());
            }
        }
        assert!(
            kind.build(&good[..good.len() - 1]).is_err(),
            "arity of {}",
            kind.id()
        );
    }
}

#[test]
fn every_effect_explains_itself_and_round_trips_its_params() {
    for kind in REGISTRY {
        let values: Vec<f64> = kind
            .schema()
            .iter()
            .map(|s| (s.bounds.0.max(0.0) + s.bounds.1.min(1.0)) / 2.0)
            .map(|v| if v == 0.0 { 0.5 } else { v })
            .collect();
        let values = match kind.id() {
            "g_sensitivity" => vec![1.0, 0.5],
            "noise_burst" => vec![1.0, 2.0, 3.0],
            _ => values,
        };
        let effect = kind.build(&values).unwrap();
        let back: Vec<f64> = effect.params().iter().map(|p| p.value).collect();
        assert_eq!(back, values, "{}", kind.id());
        let e = effect.explain();
        assert!(!e.sentence.is_empty() && !e.reference.is_empty());
        // The five terms of IEEE 952's model cite the clause that derives their signature.
        let clause = match kind.id() {
            "quantization" => Some("Annex C.1"),
            "white" => Some("Annex C.2"),
            "bias_instability" => Some("Annex C.3"),
            "random_walk" => Some("Annex C.4"),
            "ramp" => Some("Annex C.5"),
            _ => None,
        };
        if let Some(clause) = clause {
            assert!(e.reference.starts_with("IEEE Std 952-1997 ") && e.reference.contains(clause), "{}: {}", kind.id(), e.reference);
        }
        assert_eq!(
            effect.avar(1.0).is_some(),
            kind.domain() == Domain::Spectral,
            "{}",
            kind.id()
        );
        if let Some(slope_claim) = e.avar_slope {
            // The claimed slope is the signature's own slope (where it is a power law).
            let f = |t: f64| effect.avar(t).unwrap();
            assert!((slope(&f, 3.0) - slope_claim).abs() < 1e-6, "{}", kind.id());
        }
    }
}

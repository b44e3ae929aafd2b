//! Issue 10, done-when 1 (sized for CI): the diagnosis names each hidden effect at its stated
//! visibility in at least 90 % of recordings with its parameters within tolerance in at least 90 %
//! of those, and gives a clean axis a suggestion at most 2 % of the time.
//!
//! Strengths are in units of the base noise (tests/power_common): the AVAR peak ratio for spectral
//! effects, the σ of the diagnosis's own test for time-domain ones. Recordings are short (10–20 min)
//! and every N/B/K mix of common MEMS IMUs takes its turn; the full curves, with longer records and
//! more recordings per point, are in docs/model.md (`examples/diagnosis_power.rs`).

mod power_common;

use fdavar::model::effects::id;
use rand::SeedableRng;
use power_common::{
    bias_step_at, clean, clean_spiky, families, par_map, power_point, run, run_spiky, settings, wide_families, Family,
    Setting, Spikes, WIDE_GRID,
};

/// Rates (Hz) and lengths (min) of the CI-sized runs.
const GRID: &[(f64, f64)] = &[(100.0, 20.0), (200.0, 10.0), (400.0, 10.0)];

#[test]
fn clean_axes_rarely_get_a_suggestion() {
    // 36 six-axis recordings: 216 clean axes. ≤ 2 % is ≤ 4 of them.
    assert_rarely_flagged(&settings(36, GRID, 30_000), "clean axes");
}

/// Diagnoses the clean six-axis recordings of `set` and asserts that at most 2 % of their axes got
/// a suggestion (printed, each with its setting and what was suggested).
fn assert_rarely_flagged(set: &[Setting], label: &str) {
    let flagged = par_map(set, 2, |s| {
        clean(s)
            .into_iter()
            .zip(fdavar::signal::Axis::ALL)
            .filter(|(names, _)| !names.is_empty())
            .map(|(names, axis)| format!("{} Hz {} min {} seed {} {axis}: {names:?}", s.rate, s.minutes, s.mix.name, s.seed))
            .collect::<Vec<_>>()
    })
    .concat();
    println!("{label} with a suggestion: {}/{}: {flagged:#?}", flagged.len(), 6 * set.len());
    assert!(flagged.len() * 50 <= 6 * set.len(), "{flagged:#?}");
}

/// Each family at its stated visibility (tests/power_common `Family::visible`, read off the measured
/// curves in docs/model.md): named first in at least 90 % of 20 recordings, parameters within
/// tolerance in at least 90 % of those.
#[test]
fn hidden_effects_are_named_at_their_stated_visibility() {
    let set = settings(20, GRID, 40_000);
    let mut failures = Vec::new();
    for family in families() {
        let out = power_point(&family, family.visible, &set, 2);
        let detected = out.iter().filter(|o| o.detected).count();
        let ok = out.iter().filter(|o| o.params_ok).count();
        let instead: Vec<&str> = out.iter().filter_map(|o| o.instead.as_deref()).collect();
        println!("{} at {}: named first {detected}/{}, parameters ok {ok}/{detected}, instead {instead:?}", family.name, family.visible, out.len());
        if detected * 10 < 9 * out.len() || ok * 10 < 9 * detected {
            failures.push(format!("{}: {detected}/{} named, {ok} within tolerance", family.name, out.len()));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A step near an end of the record (the families place it at 25–75 %) changes the whole record's
/// Allan variance little, so a sinusoid of period about the record's drew a curve through it and
/// came first (9 of 24 recordings at 5 % and 95 %, measured), though the step's fit_error after
/// was lower (0.94–1.0 against 2.1–2.9): a located effect that explains the record better comes
/// first (`diagnose::best_first`).
#[test]
fn a_step_near_an_end_of_the_record_is_named_a_step() {
    let set = settings(12, GRID, 4242);
    let outcomes = par_map(&set, 2, |s| {
        let axis = fdavar::signal::Axis::ALL[(s.seed % 6) as usize];
        let fraction = if s.seed % 2 == 0 { 0.95 } else { 0.06 };
        run(s, &bias_step_at(s, axis, 24.0, fraction))
    });
    let named = outcomes.iter().filter(|o| o.detected).count();
    let instead: Vec<_> = outcomes.iter().filter_map(|o| o.instead.clone()).collect();
    println!("a step at 6 % or 95 % of the record, 24 σ: named first {named}/{}, instead {instead:?}", outcomes.len());
    assert!(named * 10 >= 9 * outcomes.len(), "{named}/{}: {instead:?}", outcomes.len());
}

/// Rates and lengths no threshold was tuned on (docs/model.md, "Power and false alarms"): a
/// logger's 1 Hz over 10 h, 10 Hz over an hour, 1 kHz over 10 min.
const FAR_GRID: &[(f64, f64)] = &[(1.0, 600.0), (10.0, 60.0), (1000.0, 10.0)];

/// Clean axes at the far rates: a suggestion on at most 2 % of 72 (measured with the ad-hoc
/// probe of docs/model.md: 0 of 288 at 1 Hz, 10 Hz and 1 kHz).
#[test]
fn clean_axes_at_far_rates_rarely_get_a_suggestion() {
    assert_rarely_flagged(&settings(12, FAR_GRID, 50_000), "clean axes at far rates");
}

/// Every family at its stated visibility at 10 Hz and 1 kHz (four recordings each): named first
/// on at least 90 % of all of them, parameters within tolerance on at least 90 % of those
/// (measured with the probe: 16/16 named per family, 15–16 within tolerance). At 1 kHz only: the
/// second line (at up to 7.3 Hz, above 10 Hz's Nyquist frequency) and the low-pass, whose
/// cut-off is measured less well at low rates (docs/model.md, "Known limits": at 10 Hz for an
/// hour 2 of these seeds' 2 were 1.8 and 1.2 tolerances off). 1 Hz is left out: the families'
/// Gauss–Markov time constants of 0.5 and 2 s are a filter's there.
#[test]
fn hidden_effects_are_named_at_far_rates() {
    let both = settings(4, &FAR_GRID[1..], 60_000);
    let fast = settings(4, &FAR_GRID[2..], 60_000);
    assert_mostly_named(families(), |family| {
        if [id::VIBRATION, id::BANDWIDTH].contains(&family.name) {
            fast.clone()
        } else {
            both.clone()
        }
    });
}

/// Each family at its stated visibility on the settings `set_of` gives it; asserts, over all the
/// recordings pooled, that at least 90 % were named first and at least 90 % of those had their
/// parameters within tolerance (each family's counts printed).
fn assert_mostly_named(families: Vec<Family>, set_of: impl Fn(&Family) -> Vec<Setting>) {
    let mut lines = Vec::new();
    let (mut total, mut named, mut within) = (0, 0, 0);
    for family in families {
        let out = power_point(&family, family.visible, &set_of(&family), 2);
        let detected = out.iter().filter(|o| o.detected).count();
        let ok = out.iter().filter(|o| o.params_ok).count();
        (total, named, within) = (total + out.len(), named + detected, within + ok);
        lines.push(format!("{}: named {detected}/{}, within tolerance {ok}", family.name, out.len()));
    }
    println!("{lines:#?}");
    assert!(named * 10 >= 9 * total && within * 10 >= 9 * named, "named {named}/{total}, within {within}: {lines:#?}");
}

/// Every family at its stated visibility with its parameters drawn from wide continuous ranges
/// (`power_common::wide_families`: a line from six periods per record to 0.4 × the rate, a step
/// anywhere in 10–90 % of the record, a burst over 3–40 % of it, …) at 30–400 Hz over 10–90 min,
/// twelve recordings each: named first on at least 90 % of all of them, parameters within
/// tolerance on at least 90 % of those. Measured with `examples/diagnosis_power.rs wide 60`
/// (docs/model.md, "Parameters drawn wide"): 1199 of 1200 named, 1178 within tolerance.
#[test]
fn hidden_effects_are_named_with_parameters_drawn_wide() {
    let set = settings(12, WIDE_GRID, 70_000);
    assert_mostly_named(wide_families(), |_| set.clone());
}

/// Isolated spikes of a real sensor's size (one sample in 2 000 at ±30σ: excess kurtosis about
/// 190; the XSens MTi-G gyro of docs/model.md, "Heavy tails", reads 117) on the settings of the
/// stated-visibility test.
const SPIKES: Spikes = Spikes { share: 5e-4, size: 30.0 };

/// A noise burst in such spiky noise (issue 10; docs/model.md, "Heavy tails"): named first in at
/// least 90 % of the 20 recordings at three times its stated visibility, its parameters within
/// tolerance in at least 90 % of those. The burst search and its test read the record without its
/// isolated spikes (`timedomain::despiked`). Measured (2026-11-29) at 1×, 1.5×, 2× and 3× the
/// stated visibility: 13, 15, 16 and 19 of 20, every one within tolerance; before, at 2× and 3×:
/// 4 (none within tolerance: the spikes were found) and 13 (6 within). Why not 90 % at 1×: the
/// test now passes on all 20 (likelihood ratio 105–181 against a threshold of 15, with the first
/// despiking), but a located
/// effect must also lower fit_error, and the Allan variance of a spiky record scatters too much
/// (its EDF widened for the spikes) to show a ×1.1 burst over a tenth of the record.
#[test]
fn a_noise_burst_is_named_in_spiky_noise() {
    let set = settings(20, GRID, 40_000);
    let family = families().into_iter().find(|f| f.name == id::NOISE_BURST).unwrap();
    let out = par_map(&set, 2, |s| {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s.seed ^ 0x9e37_79b9);
        run_spiky(s, &(family.make)(s, 3.0 * family.visible, &mut rng), SPIKES)
    });
    let detected = out.iter().filter(|o| o.detected).count();
    let ok = out.iter().filter(|o| o.params_ok).count();
    let suggested: Vec<&Vec<String>> = out.iter().map(|o| &o.suggested).collect();
    println!("noise_burst at 3 x {} in spiky noise: named first {detected}/{}, within tolerance {ok}: {suggested:?}", family.visible, out.len());
    assert!(detected * 10 >= 9 * out.len() && ok * 10 >= 9 * detected, "{detected}/{}, {ok} within: {suggested:?}", out.len());
}

/// Clean axes with isolated spikes: a suggestion on at most 2 % of 216 (measured 0, before and
/// after the burst search learned to read past spikes; with the first despiking, a single pass
/// that missed spikes side by side, 3 false bursts of one second each). Smaller spikes, other
/// rates and lengths: docs/model.md, "Heavy tails" (1.4 % of 1 152 clean axes, 1.2 % before).
#[test]
fn clean_spiky_axes_rarely_get_a_suggestion() {
    let set = settings(36, GRID, 30_000);
    let flagged: Vec<String> = par_map(&set, 2, |s| {
        let axes = clean_spiky(s, SPIKES).into_iter().zip(fdavar::signal::Axis::ALL);
        axes.filter(|(names, _)| !names.is_empty())
            .map(|(names, axis)| format!("{} Hz seed {} {axis}: {names:?}", s.rate, s.seed))
            .collect::<Vec<_>>()
    })
    .concat();
    println!("clean spiky axes with a suggestion: {}/{}: {flagged:#?}", flagged.len(), 6 * set.len());
    assert!(flagged.len() * 50 <= 6 * set.len(), "{flagged:#?}");
}

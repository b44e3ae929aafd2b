//! Issue 10, done-when 1 (sized for CI): the diagnosis names each hidden effect at its stated
//! visibility in at least 90 % of recordings with its parameters within tolerance in at least 90 %
//! of those, and gives a clean axis a suggestion at most 2 % of the time.
//!
//! Strengths are in units of the base noise (tests/power_common): the AVAR peak ratio for spectral
//! effects, the σ of the diagnosis's own test for time-domain ones. Recordings are short (10–20 min)
//! and every N/B/K mix of common MEMS IMUs takes its turn; the full curves, with longer records and
//! more recordings per point, are in docs/model.md (`examples/diagnosis_power.rs`).

mod power_common;

use power_common::{bias_step_at, clean, families, par_map, power_point, run, settings};

/// Rates (Hz) and lengths (min) of the CI-sized runs.
const GRID: &[(f64, f64)] = &[(100.0, 20.0), (200.0, 10.0), (400.0, 10.0)];

#[test]
fn clean_axes_rarely_get_a_suggestion() {
    // 36 six-axis recordings: 216 clean axes. ≤ 2 % is ≤ 4 of them.
    let set = settings(36, GRID, 30_000);
    let flagged: Vec<String> = par_map(&set, 2, |s| {
        clean(s)
            .into_iter()
            .zip(fdavar::signal::Axis::ALL)
            .filter(|(names, _)| !names.is_empty())
            .map(|(names, axis)| format!("{} Hz {} min {} seed {} {axis}: {names:?}", s.rate, s.minutes, s.mix.name, s.seed))
            .collect::<Vec<_>>()
    })
    .concat();
    println!("clean axes with a suggestion: {}/{}: {flagged:#?}", flagged.len(), 6 * set.len());
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

//! The text of `fdavar fit|diagnose` (issue 12, "text output a newcomer trips on"), line by line
//! against the `--json` of the same command: every parameter with its unit and value, a term fitted
//! to 0 as "not resolved" with its 2σ bound, an axis-valued parameter by its name, times in
//! seconds, no `3.0000e1`, and a model that fails in time says so on its `failing tau` line.
use serde_json::Value;
use std::process::Command;

/// The bundled recordings, from the repository root.
const EFFECTS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/effects");
const SEED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/seed_2016");
/// fit_error above which the CLI reports a failing model.
const FAILING: f64 = 2.0;

/// `fdavar ARGS` (text) and `fdavar ARGS --json`.
fn text_and_json(args: &[&str]) -> (String, Value) {
    let run = |extra: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_fdavar")).args(args).args(extra).output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    };
    (run(&[]), serde_json::from_str(&run(&["--json"])).unwrap())
}

/// The text's block of one axis: from its header line to the next axis's.
fn block<'a>(text: &'a str, axis: &str) -> Vec<&'a str> {
    let mut lines = text.lines().skip_while(|l| !l.starts_with(&format!("{axis}  model ")));
    let head = lines.next().unwrap_or_else(|| panic!("no {axis} in\n{text}"));
    std::iter::once(head).chain(lines.take_while(|l| l.starts_with(' '))).collect()
}

/// The number that starts `s` (up to the first space or comma).
fn leading_number(s: &str) -> f64 {
    let end = s.find([' ', ',', ')']).unwrap_or(s.len());
    s[..end].parse().unwrap_or_else(|e| panic!("{s:?}: {e}"))
}

/// Checks one parameter's text (what follows `name ` or `name = `) against its JSON object.
fn check_param(axis: &str, name: &str, shown: &str, p: &Value) {
    let unit = p["unit"].as_str().unwrap();
    let what = format!("{axis} {name}: {shown:?} vs {p}");
    match (&p["value"], p["sigma"].as_f64()) {
        (Value::String(axis_name), _) => {
            assert_eq!(unit, "axis", "{what}");
            assert!(shown.starts_with(axis_name.as_str()), "{what}");
        }
        (v, Some(sigma)) if v.as_f64() == Some(0.0) => {
            let bound = shown.strip_prefix("not resolved (< ").unwrap_or_else(|| panic!("{what}"));
            // The bound 2σ to 3 significant digits, then the unit.
            let b = leading_number(bound);
            assert!((b - 2.0 * sigma).abs() <= 5e-3 * 2.0 * sigma, "{what}");
            assert!(bound.contains(&format!(" {unit}, 2σ)")), "{what}");
        }
        (v, sigma) => {
            let value = v.as_f64().unwrap();
            // 5 significant digits.
            assert!((leading_number(shown) - value).abs() <= 5e-5 * value.abs(), "{what}");
            if let Some(sigma) = sigma {
                let after = shown.split(" ± ").nth(1).unwrap_or_else(|| panic!("{what}"));
                assert!((leading_number(after) - sigma).abs() <= 5e-3 * sigma, "{what}");
            }
            if unit != "1" {
                assert!(shown.contains(&format!(" {unit}")), "{what}");
            }
        }
    }
}

#[test]
fn every_parameter_is_printed_with_its_unit_as_the_json_has_it() {
    let (text, json) = text_and_json(&["diagnose", EFFECTS]);
    let mut seen = (0, 0, 0, 0); // (coefficients, unresolved, axis-valued, seconds)
    for a in json["axes"].as_array().unwrap() {
        let axis = a["axis"].as_str().unwrap();
        let lines = block(&text, axis);
        for (effect, params) in a["coefficients"].as_object().unwrap() {
            for (name, p) in params.as_object().unwrap() {
                let line = lines
                    .iter()
                    .find(|l| l.split_whitespace().take(2).eq([effect.as_str(), name.as_str()]))
                    .unwrap_or_else(|| panic!("{axis}: no line for {effect} {name}"));
                let shown = line.trim_start()[effect.len()..].trim_start()[name.len()..].trim_start();
                check_param(axis, name, shown, p);
                seen.0 += 1;
                seen.1 += usize::from(p["value"].as_f64() == Some(0.0));
            }
        }
        for (i, s) in a["suggestions"].as_array().unwrap().iter().enumerate() {
            // A suggestion weighed with others added says so: `add vibration with bandwidth and sinusoid (`.
            let given: Vec<&str> = s["given"].as_array().unwrap().iter().map(|g| g.as_str().unwrap()).collect();
            let given = if given.is_empty() { String::new() } else { format!(" with {}", given.join(" and ")) };
            let head = format!("  suggestion {}: add {}{given} (", i + 1, s["effect"].as_str().unwrap());
            let line = lines.iter().find(|l| l.starts_with(&head)).unwrap_or_else(|| panic!("{axis}: {head}"));
            for (name, p) in s["params"].as_object().unwrap() {
                let at = line.find(&format!("{name} = ")).unwrap_or_else(|| panic!("{axis}: {name} in {line}"));
                check_param(axis, name, &line[at + name.len() + 3..], p);
                seen.2 += usize::from(p["unit"] == "axis");
                seen.3 += usize::from(p["unit"] == "s");
            }
        }
    }
    // The recording exercises each case: three coefficients per axis, some fitted to 0, the
    // g_sensitivity source axis and a burst's start and end in seconds.
    assert_eq!(seen.0, 18);
    assert!(seen.1 > 0 && seen.2 > 0 && seen.3 > 0, "{seen:?}");
    // No number with a positive exponent below 10⁶ (`3.0000e1`); sig() writes those plainly.
    let positive_exponent = text
        .split(|c: char| c.is_whitespace() || c == ',' || c == '(' || c == ')')
        .find(|w| w.split_once('e').is_some_and(|(m, e)| m.parse::<f64>().is_ok() && e.parse::<u32>().is_ok_and(|e| e < 6)));
    assert_eq!(positive_exponent, None, "{text}");
}

/// The worst departure of a `failing in time` line (`worst +97.8 % at τ 0.03 s`, `worst ×0.24 at
/// τ 0.03 s`): the ratio of Allan variances, and τ as written.
fn worst_of(line: &str) -> (f64, &str) {
    let worst = line.split(", worst ").nth(1).unwrap_or_else(|| panic!("no worst point: {line}"));
    let (change, rest) = worst.split_once(" at τ ").unwrap();
    let ratio = match change.strip_prefix('×') {
        Some(factor) => factor.parse::<f64>().unwrap(),
        None => 1.0 + change.trim_end_matches(" %").parse::<f64>().unwrap() / 100.0,
    };
    (ratio, rest.split_once(" s").unwrap().0)
}

#[test]
fn a_model_failing_in_time_says_so_on_its_failing_tau_line() {
    let (text, json) = text_and_json(&["fit", SEED, "--model", "N,B,K"]);
    let mut in_time = 0;
    for a in json["axes"].as_array().unwrap() {
        let axis = a["axis"].as_str().unwrap();
        let lines = block(&text, axis);
        let failing = lines.iter().find(|l| l.starts_with("  failing tau: ")).unwrap();
        // Failing over τ or in time (the spans' error).
        let fails = a["fit_error"].as_f64().unwrap().max(a["span_fit_error"].as_f64().unwrap()) > FAILING;
        match (a["failing_tau"].as_array().unwrap().is_empty(), fails) {
            (true, true) => {
                in_time += 1;
                assert!(failing.contains("the failure is in time"), "{axis}: {failing}");
                let spans = !a["failing_spans"].as_array().unwrap().is_empty();
                let in_time_line = lines.iter().find(|l| l.starts_with("  failing in time: "));
                assert_eq!(in_time_line.is_some(), spans, "{axis}");
                // N,B,K fitted to the whole record averages the quiet and the loud thirds: the
                // spans over the burst lie above it, those before and after it below.
                if let Some(line) = in_time_line {
                    assert!(line.contains(" s, louder and quieter in turn, worst "), "{axis}: {line}");
                    // The worst departure is a quiet span at τ0, where the EDF is largest: its
                    // variance σ² against the model's time average (σ² + 9σ² + σ²)/3, 3/11 = 0.27
                    // (the seed's truth: σ triples for the middle third).
                    let (ratio, tau) = worst_of(line);
                    assert!((0.2..=0.36).contains(&ratio), "{axis}: {line}");
                    assert_eq!(tau, "0.03", "{axis}: {line}");
                }
            }
            (true, false) => assert_eq!(*failing, "  failing tau: none", "{axis}"),
            (false, _) => assert!(!failing.contains("none"), "{axis}: {failing}"),
        }
    }
    // The seed's recording: the noise triples for a third of the record, on every axis.
    assert!(in_time > 0, "{text}");
}

/// A failing interval says on which side of the model its spans lie, and by how much at its worst
/// point: on bags/effects, gyro_z's spans all lie above N,B,K (its truth adds a Gauss–Markov bias
/// and a g-sensitivity to the white noise, and the whole-record fit follows neither).
#[test]
fn a_failing_interval_says_whether_the_noise_there_is_louder_or_quieter() {
    let (text, _) = text_and_json(&["fit", EFFECTS, "--model", "N,B,K", "--axis", "gyro_z"]);
    let line = block(&text, "gyro_z").into_iter().find(|l| l.starts_with("  failing in time: ")).unwrap();
    assert!(line.starts_with("  failing in time: 0-120 s, louder than the model, worst "), "{line}");
    // Its worst point: about twice the model's Allan variance (a Gauss–Markov process the
    // whole-record N,B,K does not follow).
    let (ratio, _) = worst_of(line);
    assert!((1.5..3.0).contains(&ratio), "{line}");
    assert!(line.contains(" s (span_fit_error "), "{line}");
}

/// The header gives fit_error and, where the record was checked on spans, span_fit_error, the
/// numbers of the JSON; a record too short for spans (3 s: no span holds a point of EDF ≥ 20 at
/// τ beyond τ0) has no span_fit_error at all — not a 0 that would read as a perfect fit.
#[test]
fn the_header_gives_span_fit_error_only_where_the_spans_were_checked() {
    let (text, json) = text_and_json(&["fit", SEED, "--model", "N,B,K", "--axis", "gyro_x"]);
    let a = &json["axes"][0];
    let (whole, spans) = (a["fit_error"].as_f64().unwrap(), a["span_fit_error"].as_f64().unwrap());
    let head = block(&text, "gyro_x")[0];
    assert!(head.ends_with(&format!("  fit_error {whole:.2}  span_fit_error {spans:.2}")), "{head}");
    // The seed's tripled middle third: the curve fits, the spans do not.
    assert!(whole < FAILING && spans > FAILING, "{whole} {spans}");

    let (text, json) = text_and_json(&["fit", SEED, "--model", "N,B,K", "--axis", "gyro_x", "--first", "100"]);
    let a = &json["axes"][0];
    assert!(a.get("span_fit_error").is_none(), "{a}");
    let head = block(&text, "gyro_x")[0];
    assert!(head.ends_with(&format!("  fit_error {:.2}", a["fit_error"].as_f64().unwrap())), "{head}");
}

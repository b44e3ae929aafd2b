//! Issue 10, Build 4: a second vibration line (`vibration`), weighed by the diagnosis beside a
//! `sinusoid` (`EffectKind::follows`). From N,B,K,sinusoid on recordings with one line per axis no
//! axis gets any suggestion (the false-alarm budget is 2 %: none of 48); with two lines per axis
//! `vibration` is named first, at the line the sinusoid did not take (frequency within 10 %), on at
//! least 90 % of the axes (measured 23 of 24: the miss is a 36.5 Hz line on 100 Hz accel_x, which
//! names quantization first and the line second).
//!
//! Recordings from the real simulator (tests/model_common): N, B, K on six axes, 20 min at 100 or
//! 200 Hz, a line on every axis (gyro 1e-3 rad/s, accel 1.3e-2 m/s², at 0.05–5 Hz), on every third
//! recording a second one 0.6× as strong at 7.3× the frequency.

mod model_common;

use fdavar::model::{diagnose, FitOptions, ModelSpec};
use fdavar::signal::Axis;
use model_common::{recording, KINDS};

const FREQS: [f64; 6] = [0.05, 0.2, 1.0, 5.0, 0.1, 2.0];

#[test]
fn a_second_line_is_named_beside_the_first_and_one_line_gets_nothing() {
    let spec = ModelSpec::parse_in("N,B,K,sinusoid", KINDS).unwrap();
    let (mut one, mut flagged, mut two, mut named) = (0, Vec::new(), 0, 0);
    for seed in 0..12u64 {
        let rate = if seed % 2 == 0 { 100.0 } else { 200.0 };
        let second = seed % 3 == 0;
        let line = |i: usize| FREQS[(i + seed as usize) % FREQS.len()];
        let extra: Vec<_> = Axis::ALL
            .iter()
            .enumerate()
            .flat_map(|(i, &a)| {
                let amp = if a.is_gyro() { 1e-3 } else { 1.3e-2 };
                let mut v = vec![(a, ("sinusoid", vec![amp, line(i)]))];
                if second {
                    v.push((a, ("vibration", vec![0.6 * amp, 7.3 * line(i)])));
                }
                v
            })
            .collect();
        let rec = recording(500 + seed, rate, 20.0, &extra, &[]);
        for (i, axis) in Axis::ALL.into_iter().enumerate() {
            let d = diagnose(&rec.input(axis), &spec, KINDS, &FitOptions::default()).unwrap();
            let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
            if !second {
                one += 1;
                if !names.is_empty() {
                    flagged.push(format!("seed {seed} {axis}: {names:?}"));
                }
                continue;
            }
            two += 1;
            // The fitted sinusoid takes one of the two lines; the suggestion must be the other.
            let taken = d.fit.term("sinusoid").and_then(|t| t.param("frequency_hz")).map_or(0.0, |p| p.value);
            let other = [line(i), 7.3 * line(i)]
                .into_iter()
                .max_by(|a, b| (a / taken).ln().abs().total_cmp(&(b / taken).ln().abs()))
                .unwrap();
            let first = d.suggestions.first();
            let ok = first.is_some_and(|s| {
                s.effect == "vibration"
                    && s.params.iter().any(|p| p.name == "frequency_hz" && (p.value / other - 1.0).abs() <= 0.10)
            });
            println!("seed {seed} {axis}: lines {:.2} and {:.2} Hz, sinusoid at {taken:.3}: {names:?}", line(i), 7.3 * line(i));
            named += usize::from(ok);
        }
    }
    println!("one line: {}/{one} axes with a suggestion {flagged:?}; two lines: vibration first {named}/{two}", flagged.len());
    assert!(flagged.is_empty(), "{flagged:?}");
    assert!(10 * named >= 9 * two, "vibration named first on {named} of {two}");
}

//! Calibration and power curves of the diagnosis (issue 10): how often a clean axis gets a
//! suggestion, and how often a hidden effect of a given strength is named.
//!
//! ```text
//! cargo run --release --no-default-features --example diagnosis_power -- null RECORDINGS [SEED] [RATE:MINUTES,…]
//! cargo run --release --no-default-features --example diagnosis_power -- power PER_POINT [SEED] [PNG|-] [FAMILY,…]
//! ```
//! `null` simulates clean six-axis recordings over 100–400 Hz, 20 min–2 h and the N/B/K mixes of
//! `tests/power_common` and prints every candidate the diagnosis weighed (CSV on stdout; the clean
//! axes that got a suggestion on stderr); a list of `RATE:MINUTES` pairs (e.g. `1000:10,2000:5`)
//! replaces that grid, to check rates and lengths beyond it. `power` hides each effect at a ladder of strengths in
//! PER_POINT recordings per point (100/200/400 Hz, 20 and 60 min, every mix) and prints a markdown
//! table; with PNG it also draws the curves; with a list of families (effect ids), only those.
//! `visible` runs each family (or those listed) at its stated visibility only and also counts the
//! detections that got a further suggestion beside the truth (a false alarm of the later rounds).
//! `low-pass` does both on a sensor whose white noise passes a first-order low-pass at CUTOFF·rate
//! (default 0.3) on every axis: each family at its stated visibility, detected when named first or
//! second beside `bandwidth` (docs/model.md, "Two effects at once"), and the clean axes that got
//! anything but `bandwidth` (not when families are listed). Runs on two threads.
//! `wide` is `visible` with the parameters drawn from wide continuous ranges
//! (`power_common::wide_families`) over the rates and lengths of `power_common::WIDE_GRID`, at
//! TIMES × the stated visibility (default 1; below 1, list the families without `bandwidth`,
//! whose cut-off would then lie beyond twice the rate, which the simulator refuses).
//! ```text
//! cargo run --release --no-default-features --example diagnosis_power -- visible PER_POINT [SEED] [FAMILY,…]
//! cargo run --release --no-default-features --example diagnosis_power -- low-pass PER_POINT [SEED] [CUTOFF] [FAMILY,…]
//! cargo run --release --no-default-features --example diagnosis_power -- wide PER_POINT [SEED] [TIMES] [FAMILY,…]
//! ```

#[path = "../tests/power_common/mod.rs"]
mod power_common;

use fdavar::model::effects::{id, REGISTRY};
use fdavar::model::{diagnose, FitOptions, ModelSpec};
use fdavar::signal::Axis;
use plotters::prelude::*;
use power_common::{
    clean_low_pass, families, par_map, power_point, record, run, run_low_pass, settings, spec_yaml, wide_families, Scale,
    WIDE_GRID,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Rates (Hz) and lengths (min) of the null calibration: short records three times as often as
/// the long ones (cost grows with rate × length).
const NULL_GRID: &[(f64, f64)] = &[
    (100.0, 20.0),
    (200.0, 20.0),
    (400.0, 20.0),
    (100.0, 60.0),
    (200.0, 60.0),
    (100.0, 120.0),
    (100.0, 20.0),
    (200.0, 20.0),
    (400.0, 20.0),
    (400.0, 60.0),
    (200.0, 120.0),
    (400.0, 120.0),
    (100.0, 20.0),
    (200.0, 20.0),
    (400.0, 20.0),
    (100.0, 60.0),
];

/// Rates and lengths of the power curves.
const POWER_GRID: &[(f64, f64)] = &[(100.0, 20.0), (200.0, 20.0), (400.0, 20.0), (100.0, 60.0)];

/// Strengths of a scale: AVAR peak ratio, σ of the test, AVAR deficit.
fn ladder(scale: Scale) -> &'static [f64] {
    match scale {
        Scale::AvarPeak => &[0.5, 1.0, 2.0, 4.0, 8.0, 16.0],
        Scale::TestSigma => &[4.0, 8.0, 12.0, 16.0, 24.0],
        // From 0.12: a smaller deficit needs a cut-off above twice the rate (the simulator's bound).
        Scale::AvarDeficit => &[0.12, 0.16, 0.2, 0.3, 0.4, 0.5],
    }
}

/// `RATE:MINUTES,…` as a grid of (Hz, minutes).
fn parse_grid(list: &str) -> Vec<(f64, f64)> {
    list.split(',')
        .map(|pair| {
            let parsed = pair.split_once(':').and_then(|(r, m)| Some((r.parse().ok()?, m.parse().ok()?)));
            parsed.unwrap_or_else(|| panic!("{pair:?} is not RATE:MINUTES (e.g. 1000:10)"))
        })
        .collect()
}

fn null(recordings: usize, seed: u64, grid: &[(f64, f64)]) {
    let nbk = ModelSpec::parse_in("N,B,K", REGISTRY).unwrap();
    let set = settings(recordings, grid, seed);
    println!("rate,minutes,mix,seed,axis,effect,statistic,threshold,p,significant");
    let rows = par_map(&set, 2, |s| {
        let rec = record(&spec_yaml(s, &Axis::ALL, &[], &[]));
        let mut lines = Vec::new();
        let mut flagged = Vec::new();
        for axis in Axis::ALL {
            let d = diagnose(&rec.input(axis), &nbk, REGISTRY, &FitOptions::default()).unwrap();
            if !d.suggestions.is_empty() {
                let names: Vec<&str> = d.suggestions.iter().map(|x| x.effect.as_str()).collect();
                flagged.push(format!("{} Hz {} min {} seed {} {axis}: {names:?}", s.rate, s.minutes, s.mix.name, s.seed));
            }
            for w in &d.weighed {
                lines.push(format!(
                    "{},{},{},{},{axis},{},{:.4},{:.4},{},{}",
                    s.rate,
                    s.minutes,
                    s.mix.name,
                    s.seed,
                    w.effect,
                    w.statistic,
                    w.threshold,
                    w.p_value.map_or(String::new(), |p| format!("{p:.3e}")),
                    w.significant
                ));
            }
        }
        (lines, flagged)
    });
    let mut axes = 0;
    let mut flagged = 0;
    for (lines, f) in rows {
        axes += 6;
        flagged += f.len();
        lines.iter().for_each(|l| println!("{l}"));
        f.iter().for_each(|l| eprintln!("{l}"));
    }
    eprintln!("clean axes with a suggestion: {flagged}/{axes}");
}

/// The families at their stated visibility and the clean axes, on a low-pass sensor.
fn low_pass(per_point: usize, seed: u64, cutoff_per_rate: f64, only: Option<&str>) {
    let set = settings(per_point, POWER_GRID, seed);
    println!("low-pass at {cutoff_per_rate}·rate on every axis; {} recordings per family", set.len());
    // Without a burst (the simulator's scales `white`, which a low-pass sensor lacks) and the
    // low-pass itself.
    let skipped = |f: &&power_common::Family| f.scale != Scale::AvarDeficit && f.name != id::NOISE_BURST;
    let chosen = families().into_iter().filter(|f| skipped(&f) && listed(f, only)).collect::<Vec<_>>();
    visible_table(&set, chosen.iter(), |s, hidden| run_low_pass(s, hidden, cutoff_per_rate), 2, 1.0);
    if only.is_some() {
        return;
    }
    let clean = par_map(&set, 2, |s| clean_low_pass(s, cutoff_per_rate));
    let (mut axes, mut without_filter, mut extra) = (0, 0, 0);
    for (s, per_axis) in set.iter().zip(&clean) {
        for (axis, names) in Axis::ALL.iter().zip(per_axis) {
            axes += 1;
            without_filter += usize::from(names.first().is_none_or(|n| n != id::BANDWIDTH));
            if names.len() > 1 || names.first().is_some_and(|n| n != id::BANDWIDTH) {
                extra += 1;
                eprintln!("{} Hz {} min {} seed {} {axis}: {names:?}", s.rate, s.minutes, s.mix.name, s.seed);
            }
        }
    }
    println!("clean low-pass axes: {extra}/{axes} with a suggestion besides bandwidth, {without_filter}/{axes} without bandwidth first");
}

/// Each family at its stated visibility on an ordinary sensor: detected, parameters, and how many
/// recordings got a suggestion besides the truth (a second-round false alarm).
fn visible(per_point: usize, seed: u64, only: Option<&str>) {
    let set = settings(per_point, POWER_GRID, seed);
    println!("{} recordings per family", set.len());
    let chosen = families().into_iter().filter(|f| listed(f, only)).collect::<Vec<_>>();
    visible_table(&set, chosen.iter(), run, 1, 1.0);
}

/// [`visible`] at `times` × the stated visibility with the parameters drawn wide, at the rates and
/// lengths of `WIDE_GRID`.
fn wide(per_point: usize, seed: u64, times: f64, only: Option<&str>) {
    let set = settings(per_point, WIDE_GRID, seed);
    println!("{} recordings per family, parameters drawn wide, {times} × the stated visibility", set.len());
    let chosen = wide_families().into_iter().filter(|f| listed(f, only)).collect::<Vec<_>>();
    visible_table(&set, chosen.iter(), run, 1, times);
}

/// Whether `family` is among the comma-separated effect ids of `only` (every family without it).
fn listed(family: &power_common::Family, only: Option<&str>) -> bool {
    only.is_none_or(|o| o.split(',').any(|n| n == family.name))
}

/// The table of [`visible`], [`wide`] and [`low_pass`] at `times` × each family's stated
/// visibility: `expected` is how many suggestions a detection should carry (the truth, and on a
/// low-pass sensor the filter before it); more is an extra.
fn visible_table<'a>(
    set: &[power_common::Setting],
    chosen: impl Iterator<Item = &'a power_common::Family>,
    run: impl Fn(&power_common::Setting, &power_common::Hidden) -> power_common::Outcome + Sync,
    expected: usize,
    times: f64,
) {
    println!("| effect | strength | detected | parameters within tolerance (of detected) | more suggestions (of detected) | named instead |");
    println!("|---|---|---|---|---|---|");
    for family in chosen {
        let out = par_map(set, 2, |s| {
            let mut rng = ChaCha8Rng::seed_from_u64(s.seed ^ 0x9e37_79b9);
            run(s, &(family.make)(s, times * family.visible, &mut rng))
        });
        let detected = out.iter().filter(|o| o.detected).count();
        let ok = out.iter().filter(|o| o.params_ok).count();
        let more = out.iter().filter(|o| o.detected && o.suggested.len() > expected).count();
        for (s, o) in set.iter().zip(&out).filter(|(_, o)| !o.detected || o.suggested.len() > expected) {
            let what = if o.detected { "more" } else { "missed" };
            eprintln!("{} {what}: {} Hz {} min {} seed {}: {:?}", family.name, s.rate, s.minutes, s.mix.name, s.seed, o.suggested);
        }
        println!(
            "| {} | {} | {detected}/{} | {ok}/{detected} | {more}/{detected} | {} |",
            family.name,
            times * family.visible,
            out.len(),
            named_instead(&out)
        );
    }
}

/// What the diagnosis named first instead of the hidden effect, each once, sorted.
fn named_instead(out: &[power_common::Outcome]) -> String {
    let mut instead: Vec<&str> = out.iter().filter_map(|o| o.instead.as_deref()).collect();
    instead.sort();
    instead.dedup();
    instead.join(", ")
}

/// One family's detection-rate curve: its name, strength scale and (strength, rate) points.
type Curve<'a> = (&'a str, Scale, Vec<(f64, f64)>);

fn power(per_point: usize, seed: u64, png: Option<&str>, only: Option<&str>) {
    let set = settings(per_point, POWER_GRID, seed);
    let mut curves: Vec<Curve> = Vec::new();
    println!("| effect | strength | detected | parameters within tolerance (of detected) | named instead |");
    println!("|---|---|---|---|---|");
    for family in families().into_iter().filter(|f| listed(f, only)) {
        let mut curve = Vec::new();
        for &strength in ladder(family.scale) {
            let out = power_point(&family, strength, &set, 2);
            let detected = out.iter().filter(|o| o.detected).count();
            let ok = out.iter().filter(|o| o.params_ok).count();
            let unit = match family.scale {
                Scale::AvarPeak => "× base AVAR",
                Scale::TestSigma => "σ",
                Scale::AvarDeficit => "× base AVAR below N²/τ",
            };
            println!(
                "| {} | {strength} {unit} | {detected}/{} | {ok}/{detected} | {} |",
                family.name,
                out.len(),
                named_instead(&out)
            );
            curve.push((strength, detected as f64 / out.len() as f64));
        }
        curves.push((family.name, family.scale, curve));
    }
    if let Some(path) = png {
        draw(path, &curves).unwrap();
    }
}

/// Detection rate vs strength: spectral effects left (AVAR peak ratio, log axis), time-domain
/// right (σ).
fn draw(path: &str, curves: &[Curve]) -> Result<(), Box<dyn std::error::Error>> {
    fdavar::report::figure::ensure_font()?;
    let root = BitMapBackend::new(path, (1200, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(600);
    for (area, scale) in [(left, Scale::AvarPeak), (right, Scale::TestSigma)] {
        let log = scale == Scale::AvarPeak;
        let (title, x_label, range) = if log {
            ("Spectral effects", "AVAR peak ratio (effect / base N,B,K; bandwidth: deficit), log", (-1.6f64, 1.3f64))
        } else {
            ("Time-domain effects", "strength: σ of the test under the base noise", (2.0, 26.0))
        };
        let mut chart = ChartBuilder::on(&area)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(55)
            .build_cartesian_2d(range.0..range.1, 0f64..1.02f64)?;
        let format = |x: &f64| if log { format!("{:.2}", 10f64.powf(*x)) } else { format!("{x:.0}") };
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc("hidden effect named first")
            .x_label_formatter(&format)
            .draw()?;
        // The deficit of a low-pass is an AVAR ratio too: drawn with the spectral effects.
        let mine: Vec<_> = curves.iter().filter(|c| (c.1 == Scale::TestSigma) == (scale == Scale::TestSigma)).collect();
        for (i, (name, _, pts)) in mine.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let pts: Vec<(f64, f64)> = pts.iter().map(|&(x, y)| (if log { x.log10() } else { x }, y)).collect();
            chart
                .draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))?
                .label(*name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
        }
        chart
            .draw_series(LineSeries::new(vec![(range.0, 0.9), (range.1, 0.9)], BLACK.mix(0.4)))?
            .label("90 %")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.mix(0.4)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let count = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(16);
    let seed = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(1000);
    match args.get(1).map(String::as_str) {
        Some("null") => null(count, seed, &args.get(4).map_or(NULL_GRID.to_vec(), |g| parse_grid(g))),
        Some("power") => power(
            count,
            seed,
            args.get(4).map(String::as_str).filter(|p| *p != "-"),
            args.get(5).map(String::as_str),
        ),
        Some("visible") => visible(count, seed, args.get(4).map(String::as_str)),
        Some("wide") => wide(
            count,
            seed,
            args.get(4).and_then(|a| a.parse().ok()).unwrap_or(1.0),
            args.get(5).map(String::as_str),
        ),
        Some("low-pass") => low_pass(
            count,
            seed,
            args.get(4).and_then(|a| a.parse().ok()).unwrap_or(0.3),
            args.get(5).map(String::as_str),
        ),
        _ => eprintln!("usage: diagnosis_power null|power|visible|low-pass|wide COUNT [SEED] [PNG|-|CUTOFF|TIMES] [FAMILY,…]"),
    }
}

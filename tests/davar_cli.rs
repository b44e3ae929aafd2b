//! `fdavar davar` as a user runs it: the real binary, its exit codes and its JSON.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::io::Write;
use std::process::Command;

fn fdavar() -> Command {
    Command::new(env!("CARGO_BIN_EXE_fdavar"))
}

/// 3600 samples of white noise whose deviation triples from sample 1200 to 2400 (the seed's test).
/// Plain text, or CSV with a header `time_s,rate` when `csv` is set.
fn seed_signal_file(csv: bool) -> tempfile::NamedTempFile {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut f = tempfile::NamedTempFile::new().unwrap();
    if csv {
        writeln!(f, "time_s,rate").unwrap();
    } else {
        writeln!(f, "# gyro rate, rad/s").unwrap();
    }
    for k in 0..3600 {
        let sd = if (1200..2400).contains(&k) {
            3e-3
        } else {
            1e-3
        };
        let y = 0.01 + sd * rng.sample::<f64, _>(StandardNormal);
        if csv {
            writeln!(f, "{:.2},{y:.9}", k as f64 * 0.03).unwrap();
        } else {
            writeln!(f, "{y:.9}").unwrap();
        }
    }
    f
}

#[test]
fn json_has_rows_and_the_seed_change() {
    let file = seed_signal_file(false);
    let params = concat!(env!("CARGO_MANIFEST_DIR"), "/launch_params/seed_2016.yaml");
    let out = fdavar()
        .args([
            "davar",
            file.path().to_str().unwrap(),
            "--params",
            params,
            "--json",
            "--every",
            "0.3",
        ])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(doc["tau0"].as_f64(), Some(0.03));
    let rows = doc["rows"].as_array().unwrap();
    // One row per 0.3 s (10 samples at 30 ms) of analysis time.
    let slots: Vec<i64> = rows
        .iter()
        .map(|r| (r["time_s"].as_f64().unwrap() / 0.3).floor() as i64)
        .collect();
    assert!(slots.windows(2).all(|w| w[1] == w[0] + 1), "{slots:?}");
    assert!(rows
        .iter()
        .all(|r| r["row"]["f_target"].as_f64() == Some(3.3)));
    let events = doc["events"].as_array().unwrap();
    let main = events
        .iter()
        .map(|e| &e["event"])
        .find(|e| e["factor"].as_f64().unwrap() > 4.0)
        .expect("the noise change is an event");
    let (start, end) = (
        main["start_index"].as_u64().unwrap(),
        main["end_index"].as_u64().unwrap(),
    );
    assert!(
        (1150..1260).contains(&start) && (2340..2450).contains(&end),
        "{start} {end}"
    );
}

#[test]
fn csv_has_one_line_per_row_and_tau() {
    let file = seed_signal_file(true);
    let out = fdavar()
        .args([
            "davar",
            file.path().to_str().unwrap(),
            "--column",
            "rate",
            "--rate",
            "100",
            "--csv",
            "--every",
            "5",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines();
    assert!(lines
        .next()
        .unwrap()
        .starts_with("axis,time_s,stamp_ns,index,window,f,f_target,sigma2_ref,m,tau_s,avar"));
    let lines: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(lines.iter().all(|l| l[0] == "gyro_x" && l.len() == 16));
    // The same rows as JSON: one CSV line per (row, τ), in order, with the row's index, m, τ and
    // σ²(τ) (printed to 10 significant digits).
    let json = fdavar()
        .args(["davar", file.path().to_str().unwrap(), "--column", "rate", "--rate", "100", "--json", "--every", "5"])
        .output()
        .unwrap();
    let doc: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    let points: Vec<(u64, &serde_json::Value)> = doc["rows"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| {
            let index = r["row"]["index"].as_u64().unwrap();
            r["row"]["points"].as_array().unwrap().iter().map(move |p| (index, p))
        })
        .collect();
    assert!(points.len() > 20, "{} points", points.len());
    assert_eq!(lines.len(), points.len());
    for (line, (index, p)) in lines.iter().zip(&points) {
        assert_eq!(line[3].parse::<u64>().unwrap(), *index);
        assert_eq!(line[8].parse::<u64>().unwrap(), p["m"].as_u64().unwrap());
        let (tau, avar): (f64, f64) = (line[9].parse().unwrap(), line[10].parse().unwrap());
        assert!((tau - p["tau"].as_f64().unwrap()).abs() < 1e-9, "{line:?}");
        let want = p["avar"].as_f64().unwrap();
        assert!((avar / want - 1.0).abs() < 1e-9, "{line:?}: avar {avar} vs {want}");
    }
}

#[test]
fn errors_exit_non_zero_with_a_message() {
    let file = seed_signal_file(false);
    let no_rate = fdavar()
        .args(["davar", file.path().to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(no_rate.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&no_rate.stderr).contains("--rate"));

    let mut bad = tempfile::NamedTempFile::new().unwrap();
    writeln!(
        bad,
        "fdavar:\n  ros__parameters:\n    window: {{min: 600, max: 501}}"
    )
    .unwrap();
    let bad_params = fdavar()
        .args([
            "davar",
            file.path().to_str().unwrap(),
            "--rate",
            "100",
            "--params",
            bad.path().to_str().unwrap(),
        ])
        .output()
        .unwrap();
    // A refused parameter value is a usage error (issue 13: exit 2).
    assert_eq!(bad_params.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad_params.stderr).contains("window.min"));

    let usage = fdavar()
        .args(["davar", "x.txt", "--json", "--csv"])
        .output()
        .unwrap();
    assert_eq!(usage.status.code(), Some(2));
}

/// A bag with a gap and a noise change on gyro_z: six axes analysed, the gap reported (exit 3).
#[test]
fn bag_input_runs_all_axes_and_reports_irregularities() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("imu_bag");
    let mut writer = fdavar::bag::BagWriter::create(&bag).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for k in 0..3000i64 {
        if (1000..1005).contains(&k) {
            continue; // a gap of five samples
        }
        let mut n = || 1e-3 * rng.sample::<f64, _>(StandardNormal);
        let burst = if (1500..2200).contains(&k) { 3.0 } else { 1.0 };
        let sample = fdavar::signal::ImuSample {
            stamp_ns: 1_000_000_000 + k * 10_000_000,
            gyro: [n(), n(), burst * n()],
            accel: [n(), n(), 9.81 + n()],
        };
        writer
            .write_imu("/imu/data", sample.stamp_ns + 500_000, &sample, "imu_link")
            .unwrap();
    }
    writer.finish().unwrap();
    let out = fdavar()
        .args(["davar", bag.to_str().unwrap(), "--json", "--every", "0.5"])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("1 gaps"));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!((doc["tau0"].as_f64().unwrap() - 0.01).abs() < 1e-9);
    assert_eq!(doc["irregularities"]["gaps"].as_u64(), Some(1));
    let axes: std::collections::BTreeSet<&str> = doc["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["axis"].as_str().unwrap())
        .collect();
    assert_eq!(axes.len(), 6);
    let changed: Vec<&str> = doc["events"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["event"]["factor"].as_f64().unwrap() > 4.0)
        .map(|e| e["axis"].as_str().unwrap())
        .collect();
    assert_eq!(changed, ["gyro_z"]);
}

/// The rows, events and τ0 of `fdavar davar BAG --json` on a bundled bag, as JSON values.
fn davar_json(bag: &str, extra: &[&str]) -> serde_json::Value {
    let params = concat!(env!("CARGO_MANIFEST_DIR"), "/launch_params/seed_2016.yaml");
    let out = fdavar()
        .args(["davar", bag, "--params", params, "--json"])
        .args(extra)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The streamed CLI (the bag read three times for the whole-record σ²_ref, never held) prints the
/// rows and events of the in-memory path: every sample read into memory, `record_variances` over
/// them, one pipeline. Both sides go through the same JSON text, so equal values mean equal bits.
#[test]
fn streamed_output_equals_the_in_memory_path() {
    use fdavar::pipeline::{record_variances, Output, Pipeline};
    let bag = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/seed_2016");
    let params = concat!(env!("CARGO_MANIFEST_DIR"), "/launch_params/seed_2016.yaml");
    let config = fdavar::params::load(std::path::Path::new(params)).unwrap();
    assert_eq!(config.sigma_ref, fdavar::pipeline::SigmaRefMode::Record);
    let reader = fdavar::bag::BagReader::open(bag).unwrap();
    let topic = reader.imu_topic(None).unwrap().name.clone();
    let samples: Vec<fdavar::signal::ImuSample> = reader
        .messages(&topic, None)
        .unwrap()
        .filter_map(|m| match m.unwrap() {
            fdavar::bag::BagMessage::Imu { sample, .. } => Some(sample),
            _ => None,
        })
        .collect();
    let mut p = Pipeline::new(
        config,
        &fdavar::signal::Axis::ALL,
        Some(record_variances(&samples)),
    )
    .unwrap();
    let mut out = Output::default();
    for s in &samples {
        p.push(s, &mut out);
    }
    p.finish(&mut out);
    let expected: serde_json::Value = serde_json::from_str(&format!(
        "{{\"rows\":{},\"events\":{},\"tau0\":{}}}",
        serde_json::to_string(&out.rows).unwrap(),
        serde_json::to_string(&out.events).unwrap(),
        serde_json::to_string(&p.tau0()).unwrap()
    ))
    .unwrap();
    let doc = davar_json(bag, &[]);
    assert_eq!(doc["rows"].as_array().unwrap().len(), out.rows.len());
    assert!(out.rows.len() > 6 * 3000, "{}", out.rows.len());
    for key in ["rows", "events", "tau0"] {
        assert!(doc[key] == expected[key], "{key} differs");
    }
    assert_eq!(doc["events"].as_array().unwrap().len(), 6, "the burst on every axis");
}

/// `--every S` keeps, per axis, exactly the first row of each interval [k·S, (k+1)·S) of analysis
/// time, and leaves the events alone.
#[test]
fn every_keeps_the_first_row_of_each_interval() {
    let bag = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/seed_2016");
    let all = davar_json(bag, &[]);
    let every = 0.5;
    let some = davar_json(bag, &["--every", "0.5"]);
    let mut seen = std::collections::BTreeSet::new();
    let expected: Vec<&serde_json::Value> = all["rows"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| {
            let slot = (r["time_s"].as_f64().unwrap() / every).floor() as i64;
            seen.insert((r["axis"].as_str().unwrap().to_string(), slot))
        })
        .collect();
    let kept: Vec<&serde_json::Value> = some["rows"].as_array().unwrap().iter().collect();
    assert_eq!(kept, expected);
    // Rows come every 30 ms: about one in 17 is kept.
    let ratio = all["rows"].as_array().unwrap().len() as f64 / kept.len() as f64;
    assert!((ratio - 0.5 / 0.03).abs() < 0.5, "{ratio}");
    assert_eq!(some["events"], all["events"]);
}

/// Issue 13: parameter values that passed validation and then panicked (capacity overflow), aborted
/// (allocation failure), ran for tens of seconds or spun forever are refused before any work: exit
/// 2 and one `fdavar: error:` line naming the parameter, within a second.
#[test]
fn values_that_crashed_or_hung_are_refused_with_exit_2() {
    let data = seed_signal_file(false);
    let cases: &[(&str, &str)] = &[
        ("window: {max: 9223372036854775807}", "window.max"),
        ("window: {max: 1000000000}", "window.max"),
        ("window: {policy: fixed, length: 1000000000}", "window.length"),
        ("window: {max: 10000000}", "window.max"),
        ("window: {policy: fixed, length: 60001}", "window.length"),
        ("window: {policy: fixed, length: 50001}\n    taus: all", "taus"),
        ("tau0: 1.0e-300", "tau0"),
        ("tau0: 1.0e-22", "tau0"),
        ("window: {step: 9223372036854775807}", "window.step"),
    ];
    for (body, name) in cases {
        let mut params = tempfile::NamedTempFile::new().unwrap();
        writeln!(params, "fdavar:\n  ros__parameters:\n    {body}").unwrap();
        let start = std::time::Instant::now();
        let out = fdavar()
            .args(["davar", data.path().to_str().unwrap(), "--rate", "33.3333"])
            .args(["--params", params.path().to_str().unwrap()])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{body}: {stderr}");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{body}: {stderr}");
        assert!(lines[0].starts_with("fdavar: error: invalid parameters in "), "{stderr}");
        assert!(lines[0].contains(&format!("parameter '{name}'")), "{body}: {stderr}");
        assert!(start.elapsed().as_secs_f64() < 5.0, "{body}: {:?}", start.elapsed());
    }
    // The largest window with the default grid, and `all` with the longest window it fits, run.
    for body in [
        "window: {policy: fixed, length: 50001}",
        "window: {policy: fixed, length: 2501}\n    taus: all",
    ] {
        let mut params = tempfile::NamedTempFile::new().unwrap();
        writeln!(params, "fdavar:\n  ros__parameters:\n    {body}").unwrap();
        let out = fdavar()
            .args(["davar", data.path().to_str().unwrap(), "--rate", "33.3333"])
            .args(["--params", params.path().to_str().unwrap()])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(0), "{body}: {}", String::from_utf8_lossy(&out.stderr));
    }
    // On a bag a given tau0 must fit the stamps (30 ms here) within a factor of 10: 1e-5 s is in
    // the range but made every interval a gap of 3000 samples (12 s for 3600 samples).
    let bag = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/seed_2016");
    let mut params = tempfile::NamedTempFile::new().unwrap();
    writeln!(params, "fdavar:\n  ros__parameters:\n    tau0: 1.0e-5").unwrap();
    let out = fdavar()
        .args(["davar", bag, "--params", params.path().to_str().unwrap()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("parameter 'tau0' = 1e-5") && stderr.contains("0.03"), "{stderr}");
    // --rate gives tau0 too: the same range.
    let out = fdavar()
        .args(["davar", data.path().to_str().unwrap(), "--rate", "1e300"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--rate") && stderr.contains("tau0"), "{stderr}");
}

/// Issue 13: `fdavar allan /dev/zero` read one endless line into memory; now the line limit stops
/// it at once (exit 1, one line naming the file and the limit).
#[cfg(unix)]
#[test]
fn a_file_without_line_breaks_is_refused() {
    let start = std::time::Instant::now();
    let out = fdavar()
        .args(["allan", "/dev/zero", "--rate", "100"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("fdavar: error: "), "{stderr}");
    assert!(stderr.contains("/dev/zero:1: line longer than 65536 bytes"), "{stderr}");
    assert!(start.elapsed().as_secs_f64() < 5.0, "{:?}", start.elapsed());
}

/// Too few samples for a first row: the summary says so, with the window the first row needs
/// (the default policy's initial window, 501 samples), instead of printing τ0 alone.
#[test]
fn a_record_shorter_than_the_first_window_says_why_it_has_no_rows() {
    let summary = |samples: usize| {
        let mut f = tempfile::NamedTempFile::new().unwrap();
        (0..samples).for_each(|k| writeln!(f, "{}", (k as f64).sin()).unwrap());
        let out = fdavar().args(["davar", f.path().to_str().unwrap(), "--rate", "100"]).output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    };
    let short = summary(500);
    assert_eq!(
        short,
        "tau0: 0.01 s\nno rows: an axis gives its first row once 501 samples fill its first window \
         (`window` in a --params file sets it)\n"
    );
    let long = summary(501);
    assert!(long.contains(": 1 rows,") && !long.contains("no rows"), "{long}");
}

/// `--out DIR`: per axis the DAVAR surface and the window trace (PNG + SVG), drawn from every row
/// the run made: the same SVG as the library draws from the rows and events `--json` prints.
#[test]
fn out_draws_the_surface_and_window_trace_of_its_rows() {
    use fdavar::pipeline::{AxisEvent, AxisRow};
    use fdavar::report::davar::DavarFigures;
    use fdavar::report::figure::{write_davar_surface, write_window_trace};
    let file = seed_signal_file(false);
    let params = concat!(env!("CARGO_MANIFEST_DIR"), "/launch_params/seed_2016.yaml");
    let dir = tempfile::tempdir().unwrap();
    let figs = dir.path().join("figs");
    let run = |extra: &[&str]| {
        let out = fdavar()
            .args(["davar", file.path().to_str().unwrap(), "--params", params])
            .args(extra)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
        out.stdout
    };
    run(&["--out", figs.to_str().unwrap()]);
    let mut names: Vec<String> =
        std::fs::read_dir(&figs).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(
        names,
        ["davar_surface_gyro_x.png", "davar_surface_gyro_x.svg", "window_trace_gyro_x.png", "window_trace_gyro_x.svg"]
    );

    let json: serde_json::Value = serde_json::from_slice(&run(&["--json"])).unwrap();
    let rows: Vec<AxisRow> = serde_json::from_value(json["rows"].clone()).unwrap();
    let events: Vec<AxisEvent> = serde_json::from_value(json["events"].clone()).unwrap();
    assert_eq!(events.len(), 1, "the seed's noise change");
    let mut want = DavarFigures::new(fdavar::signal::Axis::GyroX, Some((171, 501)));
    rows.iter().for_each(|r| want.push(r));
    events.iter().for_each(|e| want.push_event(e.axis, &e.event));
    let title = file.path().file_name().unwrap().to_string_lossy().into_owned();
    let (surface, trace) = want.figures(&title).unwrap();
    let lib = dir.path().join("lib");
    write_davar_surface(&surface, &lib.join("davar_surface_gyro_x")).unwrap();
    write_window_trace(&trace, &lib.join("window_trace_gyro_x")).unwrap();
    for name in ["davar_surface_gyro_x.svg", "window_trace_gyro_x.svg"] {
        let read = |d: &std::path::Path| std::fs::read_to_string(d.join(name)).unwrap();
        assert!(read(&figs) == read(&lib), "{name}: the CLI's figure differs from its rows'");
    }
}

/// A change event of one sample is a spike, and the summary says so: "a spike at 30.000 s (sample
/// 3000)", not "noise changed from 30.000 s to 30.000 s" (a real XSens MTi-G gyro printed 35 of
/// those); the seed's tripled span is still a change of the noise.
#[test]
fn a_one_sample_event_is_called_a_spike() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let mut f = tempfile::NamedTempFile::new().unwrap();
    for k in 0..6000 {
        let spike = if k == 3000 { 0.05 } else { 0.0 };
        writeln!(f, "{:.9}", 1e-3 * rng.sample::<f64, _>(StandardNormal) + spike).unwrap();
    }
    let out = fdavar().args(["davar", f.path().to_str().unwrap(), "--rate", "100"]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let spikes: Vec<&str> = text.lines().filter(|l| l.contains("a spike at")).collect();
    assert_eq!(spikes.len(), 1, "{text}");
    assert!(spikes[0].starts_with("  a spike at 30.000 s (sample 3000): one sample, level x"), "{text}");
    assert!(!text.contains("noise changed"), "{text}");

    let seed = seed_signal_file(false);
    let params = concat!(env!("CARGO_MANIFEST_DIR"), "/launch_params/seed_2016.yaml");
    let out = fdavar().args(["davar", seed.path().to_str().unwrap(), "--params", params]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("  noise changed from ") && !text.contains("a spike"), "{text}");
}

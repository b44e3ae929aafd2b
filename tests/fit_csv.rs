//! `fdavar fit|diagnose BAG --csv DIR` (issue 12): per axis `allan_<axis>.csv`, the Allan curve,
//! the model at the same τ and z. Checked value by value against the library's fit of the same
//! recording (the path `fdavar fit` runs), against the `--json` of the same run, and against the
//! definition of z recomputed from the CSV's own columns.
use fdavar::analysis::{Analysis, AnalysisConfig};
use fdavar::bag::{BagMessage, BagReader};
use fdavar::model::{FittedModel, ModelSpec};
use fdavar::report::fit::{ALLAN_CSV_COLUMNS, SPANS_CSV_COLUMNS};
use fdavar::signal::Axis;
use std::path::Path;
use std::process::Command;

/// The bundled clean recording (120 s of N, B, K at 100 Hz).
const CLEAN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/clean");

/// The library's fit of `axes` of a recording with `model`, fed as `fdavar fit` feeds it.
fn library_fits(bag: &Path, model: &str, axes: &[Axis]) -> Vec<FittedModel> {
    let reader = BagReader::open(bag).unwrap();
    let imu = reader.imu_topic(None).unwrap().name.clone();
    let temperature = reader.temperature_topic(None).unwrap().map(|t| t.name.clone());
    let spec = ModelSpec::parse(model).unwrap();
    let mut analysis = Analysis::new(AnalysisConfig::whole_run(&spec)).unwrap();
    for m in reader.messages(&imu, temperature.as_deref()).unwrap() {
        match m.unwrap() {
            BagMessage::Imu { sample, .. } => {
                analysis.push(&sample);
            }
            BagMessage::Temperature { sample, .. } => analysis.push_temperature(&sample),
        }
    }
    analysis.finish();
    axes.iter().map(|&a| analysis.fit(a).unwrap()).collect()
}

/// The Allan CSV's rows as numbers, after checking its header.
fn read_csv(path: &Path) -> Vec<Vec<f64>> {
    read_csv_with(path, &ALLAN_CSV_COLUMNS)
}

/// A CSV's rows as numbers, after checking that its header is `columns`.
fn read_csv_with(path: &Path, columns: &[&str]) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(columns.join(",").as_str()));
    lines
        .map(|l| l.split(',').map(|c| c.parse::<f64>().unwrap_or_else(|e| panic!("{l}: {e}"))).collect())
        .collect()
}

#[test]
fn csv_holds_the_fits_curve_model_and_z() {
    let dir = tempfile::tempdir().unwrap();
    let axes = [Axis::GyroX, Axis::AccelY];
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(["fit", CLEAN, "--model", "N,B,K", "--axis", "gyro_x", "--axis", "accel_y", "--json", "--csv"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8(out.stdout).unwrap();
    let json: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let files: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(files.len(), 4, "{files:?}");

    for (fit, reported) in library_fits(Path::new(CLEAN), "N,B,K", &axes).iter().zip(json["axes"].as_array().unwrap()) {
        // The same run as the JSON's.
        assert_eq!(reported["axis"], fit.axis.name());
        // Compared as text: serde_json's default float parser may miss the nearest f64 by an ulp.
        let fit_error = format!("\"fit_error\":{}", serde_json::to_string(&fit.fit_error).unwrap());
        assert!(stdout.contains(&fit_error), "{}: {fit_error} not in {stdout}", fit.axis);
        let rows = read_csv(&dir.path().join(format!("allan_{}.csv", fit.axis)));
        assert_eq!(rows.len(), fit.points.len(), "{}: one row per τ", fit.axis);
        assert!(rows.len() >= 20, "{}: {} τ", fit.axis, rows.len());
        for (row, p) in rows.iter().zip(&fit.points) {
            // Exact: the CSV writes each number in full (shortest round-trip form).
            let want = [
                p.tau,
                p.m as f64,
                p.measured.sqrt(),
                p.ci().0.max(0.0).sqrt(),
                p.ci().1.sqrt(),
                p.edf,
                p.model.max(0.0).sqrt(),
                p.z,
            ];
            assert_eq!(row.as_slice(), want.as_slice(), "{} τ = {}", fit.axis, p.tau);
            // z from the CSV's own columns (the squares of rounded square roots: a few ulps).
            let [_, _, adev, low, high, edf, model, z] = row[..] else { unreachable!() };
            assert!(low <= adev && adev <= high, "{} τ = {}: {row:?}", fit.axis, p.tau);
            let scale = model * model * (2.0 / edf).sqrt();
            let z_from_columns = (adev * adev - model * model) / scale;
            let ulps = 8.0 * f64::EPSILON * adev * adev / scale;
            assert!((z_from_columns - z).abs() <= ulps, "{} τ = {}: z {z} vs {z_from_columns}", fit.axis, p.tau);
        }
        // The spans: one row per span of the fit, every number in full.
        let spans = read_csv_with(&dir.path().join(format!("spans_{}.csv", fit.axis)), &SPANS_CSV_COLUMNS);
        assert_eq!(spans.len(), fit.spans.len(), "{}: one row per span", fit.axis);
        assert!(spans.len() >= 5, "{}: {} spans", fit.axis, spans.len());
        for (row, c) in spans.iter().zip(&fit.spans) {
            assert_eq!(
                row.as_slice(),
                [c.span.start_s, c.span.end_s, c.fit_error, c.mean_z, c.worst_tau, c.worst_ratio].as_slice(),
                "{}",
                fit.axis
            );
            // A mean is never larger in size than the RMS of the same numbers.
            assert!(c.mean_z.abs() <= c.fit_error * (1.0 + 1e-12), "{}: {row:?}", fit.axis);
            // The worst point is one of the span's τ on the fit's grid, its ratio a real one.
            assert!(fit.points.iter().any(|p| p.tau == c.worst_tau), "{}: worst τ {} off the grid", fit.axis, c.worst_tau);
            assert!(c.worst_ratio > 0.0 && c.worst_ratio.is_finite(), "{}: {row:?}", fit.axis);
        }
        // The whole-record fit_error is the RMS of the CSV's z.
        let zs: Vec<f64> = rows.iter().map(|r| r[7]).collect();
        let rms = (zs.iter().map(|z| z * z).sum::<f64>() / zs.len() as f64).sqrt();
        assert!((rms - fit.fit_error).abs() <= 1e-12 * fit.fit_error, "{}: {rms} vs {}", fit.axis, fit.fit_error);
    }
}

/// `diagnose --csv` writes the same curves as `fit --csv` for the model it starts from.
#[test]
fn diagnose_csv_equals_fit_csv() {
    let dir = tempfile::tempdir().unwrap();
    for command in ["fit", "diagnose"] {
        let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
            .args([command, CLEAN, "--model", "N,B,K", "--axis", "gyro_z", "--csv"])
            .arg(dir.path().join(command))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let read = |c: &str, f: &str| std::fs::read_to_string(dir.path().join(c).join(f)).unwrap();
    assert_eq!(read("fit", "allan_gyro_z.csv"), read("diagnose", "allan_gyro_z.csv"));
    assert!(read("fit", "allan_gyro_z.csv").lines().count() > 20);
    assert_eq!(read("fit", "spans_gyro_z.csv"), read("diagnose", "spans_gyro_z.csv"));
    assert!(read("fit", "spans_gyro_z.csv").lines().count() > 5);
}

/// `--record-cap`: a recording longer than the default cap (2²⁰ values per axis) is fitted from
/// τ = 2τ0 on, since its record was halved; a cap that holds it keeps τ0. Values outside
/// [2²⁰, 2²⁴] are refused with the range.
#[test]
fn record_cap_decides_whether_a_long_recording_keeps_its_shortest_tau() {
    let dir = tempfile::tempdir().unwrap();
    let spec = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/bags/specs/clean.yaml")).unwrap();
    // 1 050 000 samples at 100 Hz: 1 424 more than 2²⁰.
    let spec = spec.replace("duration_s: 120", "duration_s: 10500");
    assert!(spec.contains("duration_s: 10500"));
    std::fs::write(dir.path().join("long.yaml"), spec).unwrap();
    let bag = dir.path().join("long");
    let fdavar = || Command::new(env!("CARGO_BIN_EXE_fdavar"));
    let out = fdavar().arg("simulate").arg(dir.path().join("long.yaml")).arg("--out").arg(&bag).output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let shortest_tau = |cap: Option<&str>| {
        let csv = dir.path().join(format!("csv_{}", cap.unwrap_or("default")));
        let mut cmd = fdavar();
        cmd.arg("fit").arg(&bag).args(["--model", "N,B,K", "--axis", "gyro_x", "--csv"]).arg(&csv);
        if let Some(c) = cap {
            cmd.args(["--record-cap", c]);
        }
        let out = cmd.output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
        read_csv(&csv.join("allan_gyro_x.csv"))[0][0]
    };
    assert!((shortest_tau(None) - 0.02).abs() < 1e-9, "{}", shortest_tau(None));
    assert!((shortest_tau(Some("2097152")) - 0.01).abs() < 1e-9);
    for bad in ["1048575", "16777217", "lots"] {
        let out = fdavar().arg("diagnose").arg(CLEAN).args(["--record-cap", bad]).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{bad}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--record-cap") && err.contains("[1048576, 16777216]"), "{bad}: {err}");
    }
}

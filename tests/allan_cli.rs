//! `fdavar allan` as a user meets it: frequency input, CSV columns, the table, and clear errors.

use std::path::Path;
use std::process::{Command, Output};

fn fdavar(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .arg("allan")
        .args(args)
        .output()
        .unwrap()
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// NBS-14 frequency data (NIST SP 1065 p. 107): OADEV(1, 2) = 91.22945, 85.95287.
const NBS14_FREQ: &str = "892\n809\n823\n798\n671\n644\n883\n903\n677\n";

#[test]
fn frequency_input_gives_nbs14() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "f.txt", NBS14_FREQ);
    let o = fdavar(&[&f, "--rate", "1", "--frequency", "--taus", "all", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["data"], "frequency");
    let devs: Vec<f64> = v["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["dev"].as_f64().unwrap())
        .collect();
    assert_eq!(devs.len(), 4); // m = 1 … (10 − 1)/2
    assert!(
        (devs[0] / 91.22945 - 1.0).abs() < 1e-6 && (devs[1] / 85.95287 - 1.0).abs() < 1e-6,
        "{devs:?}"
    );
}

#[test]
fn csv_column_by_name_and_index_agree_and_rate_scales_tau() {
    let dir = tempfile::tempdir().unwrap();
    let rows: String = NBS14_FREQ
        .lines()
        .enumerate()
        .map(|(i, y)| format!("{i},{y}\n"))
        .collect();
    let f = write(dir.path(), "f.csv", &format!("t,gyro_x\n{rows}"));
    let by_name = fdavar(&[&f, "--rate", "100", "--column", "gyro_x", "--json"]);
    let by_index = fdavar(&[&f, "--rate", "100", "--column", "1", "--json"]);
    assert!(by_name.status.success(), "{}", stderr(&by_name));
    assert_eq!(by_name.stdout, by_index.stdout);
    let v: serde_json::Value = serde_json::from_slice(&by_name.stdout).unwrap();
    assert_eq!(v["tau0"], 0.01);
    assert_eq!(v["points"][0]["tau"], 0.01);
}

#[test]
fn table_has_stable32_columns() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "f.txt", NBS14_FREQ);
    let o = fdavar(&[&f, "--rate", "1", "--estimator", "mdev", "--taus", "octave"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("# Sigma Type: Modified Allan"), "{text}");
    assert!(
        text.contains("AF        Tau        #    Alpha  Min Sigma      Sigma         Max Sigma")
    );
    let first = text.lines().find(|l| !l.starts_with('#')).unwrap();
    let f: Vec<&str> = first.split_whitespace().collect();
    assert_eq!((f[0], f[2]), ("1", "8"), "{first}");
    assert!(
        (f[5].parse::<f64>().unwrap() / 91.22945 - 1.0).abs() < 1e-4,
        "{first}"
    );
}

#[test]
fn errors_are_clear_and_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let bad = write(dir.path(), "bad.txt", "# header\n1.0\n2.0\nhello\n");
    let short = write(dir.path(), "short.txt", "1.0\n2.0\n");
    let good = write(dir.path(), "good.txt", NBS14_FREQ);
    let empty = write(dir.path(), "empty.txt", "# only a comment\n\n");
    let missing = dir.path().join("nope.txt");
    let cases: [(Vec<&str>, &str); 6] = [
        (
            vec![missing.to_str().unwrap(), "--rate", "1"],
            "cannot read",
        ),
        (
            vec![&bad, "--rate", "1"],
            "bad.txt:4: not a number: 'hello'",
        ),
        (
            vec![&short, "--rate", "1", "--phase"],
            "needs at least 3 phase points, got 2",
        ),
        (
            vec![&empty, "--rate", "1"],
            "empty.txt holds no values (one number per line, '#' comments)",
        ),
        (
            vec![&good, "--rate", "0"],
            "--rate must be a positive number of Hz, got 0",
        ),
        (
            vec![&good, "--rate", "1", "--column", "gyro_x"],
            "no column named 'gyro_x'",
        ),
    ];
    for (args, want) in cases {
        let o = fdavar(&args);
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        let e = stderr(&o);
        assert!(
            e.starts_with("fdavar: error: ") && e.contains(want),
            "{args:?}: {e}"
        );
        assert_eq!(e.lines().count(), 1, "{e}");
        // A cause is said once (it was twice: in the message and as its source).
        assert!(e.matches("(os error").count() <= 1, "{e}");
    }
    // A usage error (unknown estimator) is clap's: exit 2.
    assert_eq!(
        fdavar(&[&good, "--rate", "1", "--estimator", "tdev"])
            .status
            .code(),
        Some(2)
    );
}

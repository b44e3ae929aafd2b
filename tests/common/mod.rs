//! What several test binaries share.

use std::path::PathBuf;
use std::process::Command;

/// The Python interpreter that runs `imports` (a Python statement, e.g. `import mcap, numpy`):
/// `FDAVAR_PYTHON`, else `<crate>/.venv/bin/python`. Without one, says why and how to install
/// (`requirements`: the `.ci/python-*.txt` file) and returns None, so the test skips — unless
/// `FDAVAR_REQUIRE_PYTHON=1` (CI), where a missing tool is a failure.
#[allow(dead_code)] // The figure tests include this module for `shaded` alone.
pub fn python_with(imports: &str, requirements: &str) -> Option<PathBuf> {
    let python = std::env::var_os("FDAVAR_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/python"));
    let why = match Command::new(&python).args(["-c", imports]).output() {
        Ok(out) if out.status.success() => return Some(python),
        Ok(out) => format!(
            "{}: {}",
            python.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        ),
        Err(e) => format!("{}: {e}", python.display()),
    };
    let why = format!("{why} (pip install -r {requirements} into it, or set FDAVAR_PYTHON)");
    if std::env::var("FDAVAR_REQUIRE_PYTHON").as_deref() == Ok("1") {
        panic!("Python test tools required: {why}");
    }
    eprintln!("skipping: Python test tools missing: {why}");
    None
}

/// One parameter of `fdavar fit|diagnose --json` (`{value, sigma, unit}`) as the `Coefficient`
/// message carries it, `{value, sigma, unit}` with numbers only: an axis-valued value
/// (`"accel_y"`, unit `axis`) back to its number ([`fdavar::model::effects::accel_axis`]); a
/// missing number (NaN in the message) is null on both sides.
#[allow(dead_code)] // Not every test binary that includes this module compares with messages.
pub fn param_as_message(p: &serde_json::Value) -> serde_json::Value {
    let value = match &p["value"] {
        serde_json::Value::String(name) => {
            let axis: fdavar::signal::Axis = name.parse().expect("an axis name");
            (0..3)
                .find(|&i| fdavar::model::effects::accel_axis(f64::from(i)) == Some(axis))
                .map(|i| serde_json::json!(f64::from(i)))
                .unwrap_or_else(|| panic!("{name} is not an accel axis"))
        }
        v => v.clone(),
    };
    serde_json::json!({"value": value, "sigma": p["sigma"], "unit": p["unit"]})
}

/// The shaded rectangles of a figure's SVG: the failing τ ranges and the failing spans, drawn at
/// `fill-opacity="0.16"`.
#[allow(dead_code)] // Only the figure tests count them.
pub fn shaded(svg: &str) -> usize {
    svg.split("<rect").skip(1).filter(|r| r.split('>').next().unwrap_or("").contains("0.16")).count()
}

/// Thread `tid`'s voluntary context switches in process `pid` (`voluntary_ctxt_switches` of
/// /proc/PID/task/TID/status): each sleep or park it woke from. None when the thread is gone.
#[allow(dead_code)] // Read by tests/ros_interop.rs and benches/node_load.rs only.
pub fn voluntary_switches(pid: u32, tid: &str) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/task/{tid}/status")).ok()?;
    status.lines().find_map(|l| l.strip_prefix("voluntary_ctxt_switches:"))?.trim().parse().ok()
}

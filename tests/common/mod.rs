//! What several test binaries share.

use std::path::PathBuf;
use std::process::Command;

/// The Python interpreter that runs `imports` (a Python statement, e.g. `import mcap, numpy`):
/// `FDAVAR_PYTHON`, else `<crate>/.venv/bin/python`. Without one, says why and how to install
/// (`requirements`: the `.ci/python-*.txt` file) and returns None, so the test skips — unless
/// `FDAVAR_REQUIRE_PYTHON=1` (CI), where a missing tool is a failure.
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

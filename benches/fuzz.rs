//! The long fuzz run of the bag reader and the CDR decoder (tests/fuzz_common):
//!
//! ```text
//! cargo bench --bench fuzz -- [EXECUTIONS] [SEED]      (default 10 000 000, seed 1)
//! ```
//! Prints the tallies per target every 10⁶ executions and at the end; exits 1 when any input
//! panicked (kept under the scratch directory it names). Scratch files go to /dev/shm when it
//! exists: every MCAP and sqlite3 mutant is written to a file and opened as a bag.

#[path = "../tests/fuzz_common/mod.rs"]
mod fuzz_common;

use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let executions: u64 = args
        .first()
        .and_then(|a| a.parse().ok())
        .unwrap_or(10_000_000);
    let seed: u64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(1);
    let shm = std::path::Path::new("/dev/shm");
    let dir = if shm.is_dir() {
        tempfile::tempdir_in(shm)
    } else {
        tempfile::tempdir()
    }
    .expect("scratch directory");
    let mut fuzzer = fuzz_common::Fuzzer::new(dir.path(), seed);
    // Panics are caught and counted; their default message would flood the output.
    std::panic::set_hook(Box::new(|_| {}));
    let start = Instant::now();
    let step = 1_000_000;
    let mut done = 0;
    while done < executions {
        let n = step.min(executions - done);
        fuzzer.run(n);
        done += n;
        println!(
            "{done:>11} executions in {:7.1} s, {} panics",
            start.elapsed().as_secs_f64(),
            fuzzer.total().panics
        );
    }
    for (target, t) in fuzzer.tallies {
        println!("{target:?}: {t:?}");
    }
    let total = fuzzer.total();
    println!(
        "total: {} executions in {:.1} s ({:.0}/s), {} panics",
        total.executions,
        start.elapsed().as_secs_f64(),
        total.executions as f64 / start.elapsed().as_secs_f64(),
        total.panics
    );
    if total.panics > 0 {
        let kept = dir.keep();
        println!(
            "inputs that panicked: {:?} (in {})",
            fuzzer.crashes,
            kept.display()
        );
        std::process::exit(1);
    }
}

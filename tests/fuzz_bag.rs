//! A short run of the bag/CDR fuzzer (tests/fuzz_common): 30 000 mutants of valid MCAP, sqlite3
//! and CDR inputs never panic, and enough of them still decode that the run reaches past the
//! readers' first checks. The long run (10⁷ executions, README) is `cargo bench --bench fuzz`.

mod fuzz_common;

use fuzz_common::{Fuzzer, Target};

#[test]
fn thirty_thousand_mutated_bags_and_messages_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let mut fuzzer = Fuzzer::new(dir.path(), 11);
    fuzzer.run(30_000);
    let total = fuzzer.total();
    assert_eq!(total.executions, 30_000);
    assert_eq!(
        total.panics, 0,
        "inputs that panicked: {:?}",
        fuzzer.crashes
    );
    for (target, t) in fuzzer.tallies {
        println!("{target:?}: {t:?}");
        // Every target ran, and mutants both pass (reaching the message decoders) and fail.
        assert!(t.executions > 500, "{target:?}: {t:?}");
        let share = t.decoded as f64 / t.executions as f64;
        let floor = if target == Target::Cdr { 0.3 } else { 0.05 };
        assert!(
            share > floor && share < 0.98,
            "{target:?} decoded share {share:.3}: {t:?}"
        );
    }
}

//! Every shipped spec (bags/specs/*.yaml) and the example of docs/sim.md parse and simulate, and
//! the example in the docs is the shipped `effects.yaml` word for word.

use fdavar::sim::{simulate, SimSpec};
use std::path::Path;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn shipped_specs_simulate() {
    let dir = root().join("bags/specs");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "yaml") {
            let text = std::fs::read_to_string(&path).unwrap();
            let spec =
                SimSpec::from_yaml(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let rec = simulate(&spec).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert_eq!(rec.imu.len(), spec.samples());
            count += 1;
        }
    }
    assert!(
        count >= 3,
        "expected the clean, seed_2016 and effects specs"
    );
}

#[test]
fn the_docs_example_is_the_effects_spec() {
    let doc = std::fs::read_to_string(root().join("docs/sim.md")).unwrap();
    let start = doc
        .find("```yaml\n")
        .expect("a yaml example in docs/sim.md")
        + 8;
    let end = start + doc[start..].find("```").unwrap();
    let shipped = std::fs::read_to_string(root().join("bags/specs/effects.yaml")).unwrap();
    assert_eq!(&doc[start..end], shipped);
    let spec = SimSpec::from_yaml(&shipped).unwrap();
    let truth = simulate(&spec).unwrap().truth;
    // Every effect of the vocabulary appears somewhere in the example.
    for kind in fdavar::model::effects::REGISTRY {
        let used = truth
            .axes
            .values()
            .chain(truth.vibration.values())
            .flatten()
            .any(|e| e.effect == kind.id());
        assert!(used, "docs example lacks {}", kind.id());
    }
}

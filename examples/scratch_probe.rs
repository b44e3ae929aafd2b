#[path = "../tests/power_common/mod.rs"]
mod power_common;
use fdavar::model::effects::REGISTRY;
use fdavar::model::{diagnose, FitOptions, ModelSpec};
use fdavar::signal::Axis;
use power_common::*;
fn main() {
    let nbk = ModelSpec::parse_in("N,B,K", REGISTRY).unwrap();
    for (rate, minutes, mix, seed, axis) in [(200.0, 60.0, 4, 1004, Axis::GyroX), (400.0, 60.0, 0, 1073, Axis::GyroX)] {
        let s = Setting { rate, minutes, mix: &MIXES[mix], seed };
        let rec = record(&spec_yaml(&s, &Axis::ALL, &[], &[]));
        let d = diagnose(&rec.input(axis), &nbk, REGISTRY, &FitOptions::default()).unwrap();
        for t in &d.fit.terms { println!("before {} {:?}", t.effect, t.params.iter().map(|p| p.value).collect::<Vec<_>>()); }
        for (sg, a) in d.suggestions.iter().zip(&d.after) {
            println!("{} {:?} stat {:.1} fe {:.2} -> {:.2}", sg.effect, sg.params.iter().map(|p| p.value).collect::<Vec<_>>(), sg.delta_chi2, d.fit.fit_error, sg.fit_error_after);
            for (p, q) in d.fit.points.iter().zip(&a.points) {
                println!("  tau {:9.3} meas {:.3e} before {:.3e} after {:.3e} edf {:7.1} z {:6.2} -> {:6.2}", p.tau, p.measured, p.model, q.model, q.edf, p.z, q.z);
            }
        }
    }
}

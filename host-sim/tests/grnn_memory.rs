//! The memory GRNN on the dynamic hose data, against the static map.

use dca_core::params::PlantParams;
use host_sim::model::hose::data::{DynamicData, QuasiStaticData};
use host_sim::model::hose::grnn::{SHIPPED_MEMORY_SIGMA, SHIPPED_MEMORY_TAUS_S};
use host_sim::model::hose::memory::{lowpass, static_features, MemoryGrnn};
use host_sim::model::hose::net::{score, Grnn};
use host_sim::model::plant::{HoseModel, Plant};
use host_sim::studies::grnn::closed_loop::{dt_for, real_time_factor};
use host_sim::studies::grnn::memory::{leave_one_run_out, loro_table, select};

/// The filter is exact for a pressure linear between samples: on a ramp from
/// equilibrium, lowpass(P) = P - s tau (1 - e^(-t/tau)).
#[test]
fn lowpass_is_exact_on_ramps() {
    let t: Vec<f64> = (0..200)
        .map(|i| f64::from(i) * 1e-3 + if i > 100 { 5e-4 } else { 0.0 })
        .collect();
    let p: Vec<f64> = t.iter().map(|t| 1.0 + 20.0 * t).collect();
    let f = lowpass(&t, &p, 0.01);
    for (i, (&ti, &fi)) in t.iter().zip(&f).enumerate() {
        let want = p[i] - 20.0 * 0.01 * (1.0 - (-ti / 0.01).exp());
        assert!((fi - want).abs() < 1e-12, "i {i}: {fi} vs {want}");
    }
}

/// Trained on the steps and ramp runs, tested on the sweep: the memory GRNN is
/// clearly better than the static (P, dP/dt) map trained on the same runs, and
/// far better than the paper's quasi-static map.
#[test]
fn memory_beats_static_on_held_out_sweep() {
    let d = DynamicData::shipped();
    let train = [&d.runs[0], &d.runs[1]];
    let held = &d.runs[2];
    let truth = &held.dvdt_mm3_s;
    let m = MemoryGrnn::fit_merged(&train, SHIPPED_MEMORY_TAUS_S, SHIPPED_MEMORY_SIGMA, 1, 0.05)
        .unwrap();
    let sm = score(truth, &m.predict_run(held));
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    for r in train {
        xs.extend(static_features(r));
        ys.extend_from_slice(&r.dvdt_mm3_s);
    }
    let s_net = Grnn::fit_merged(&xs, 2, &ys, 0.1, 0.01).unwrap();
    let ss = score(truth, &s_net.predict_many(&static_features(held)));
    let q = QuasiStaticData::shipped();
    let (xq, yq) = q.xy(&(0..q.samples.len()).collect::<Vec<_>>());
    let q_net = Grnn::fit2(&xq, &yq, 0.1).unwrap();
    let sq = score(truth, &q_net.predict_many(&static_features(held)));
    println!("held-out sweep: memory {sm:?}\n static (dynamic runs) {ss:?}\n static (quasi-static) {sq:?}");
    assert!(sm.vacc_rel_pct > ss.vacc_rel_pct + 10.0);
    assert!(sm.rmse < 0.7 * ss.rmse);
    assert!(sq.vacc_rel_pct < 20.0 && sq.rmse > 2.0 * sm.rmse);
}

/// Merging near-duplicate consecutive samples (as the shipped memory hose does)
/// hardly changes the network: predictions on a held-out run move by < 0.5 % of
/// the output range.
#[test]
fn merging_near_duplicates_keeps_predictions() {
    let d = DynamicData::shipped();
    let train = [&d.runs[0], &d.runs[1]];
    let full = MemoryGrnn::fit(&train, SHIPPED_MEMORY_TAUS_S, 0.1, 2).unwrap();
    let merged = MemoryGrnn::fit_merged(&train, SHIPPED_MEMORY_TAUS_S, 0.1, 2, 0.05).unwrap();
    assert!(
        merged.net.len() < full.net.len() * 3 / 4,
        "{} of {}",
        merged.net.len(),
        full.net.len()
    );
    assert_eq!(merged.net.total_count(), full.net.len() as f64);
    let (lo, hi) = full.net.output_range();
    let held = &d.runs[2];
    let idx: Vec<usize> = (0..held.len()).step_by(7).collect();
    let pf = full.predict_run(held);
    let pm = merged.predict_run(held);
    let worst = idx
        .iter()
        .map(|&i| (pf[i] - pm[i]).abs())
        .fold(0.0, f64::max);
    println!(
        "{} -> {} samples; worst prediction change {worst:.1} mm^3/s of range {:.0}",
        full.net.len(),
        merged.net.len(),
        hi - lo
    );
    assert!(worst < 5e-3 * (hi - lo));
}

/// Leave-one-run-out with every hyper-parameter chosen on the training runs, and
/// the choice of the shipped memory hose on all runs. Long (about 30 s in
/// release): `cargo test --release -p host-sim --test grnn_memory -- --ignored`.
#[test]
#[ignore]
fn leave_one_run_out_and_selection() {
    let d = DynamicData::shipped();
    let q = QuasiStaticData::shipped();
    let rows = leave_one_run_out(&d, &q, 4).unwrap();
    println!("{}", loro_table(&rows));
    for r in &rows {
        assert!(r.memory.rmse < r.static_dynamic.rmse, "run {}", r.run);
        assert!(
            r.memory.vacc_rel_pct > r.static_dynamic.vacc_rel_pct,
            "run {}",
            r.run
        );
        assert!(r.static_quasistatic.vacc_rel_pct < 20.0, "run {}", r.run);
    }
    let runs: Vec<_> = d.runs.iter().collect();
    let sel = select(&runs, 4).unwrap();
    println!(
        "all runs: taus {:?} s, sigma {}, CV VAcc {:.1} %",
        sel.taus_s, sel.sigma, sel.cv_vacc_pct
    );
    assert_eq!(sel.taus_s, SHIPPED_MEMORY_TAUS_S);
    assert_eq!(sel.sigma, SHIPPED_MEMORY_SIGMA);
}

/// Real-time factors of the GRNN plants (prints only; no timed assertion):
/// `cargo test --release -p host-sim --test grnn_memory -- --ignored --nocapture`.
#[test]
#[ignore]
fn real_time_factors() {
    for m in [HoseModel::Nonlinear, HoseModel::Grnn, HoseModel::GrnnMemory] {
        let plant = Plant::new(PlantParams::NOMINAL, m);
        for sc in ["openloop", "stepload"] {
            let best = (0..3)
                .map(|_| real_time_factor(plant.clone(), sc, dt_for(m)).unwrap())
                .fold(0.0, f64::max);
            println!(
                "{} {sc} at dt {}: {best:.1}x real time",
                m.name(),
                dt_for(m)
            );
        }
    }
}

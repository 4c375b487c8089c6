//! Run time of one diagnosis of two 10 s runs (one fit, one check) on one
//! core, over the validation suite's cases, and the share of it the
//! `sensor_calibration` and `parameters` candidates take (their fits on the
//! fit run and their gaps on the check run, timed alone). Ignored by
//! default (a measurement, minutes long): `cargo test -p host-sim --release
//! --test gap_timing -- --ignored --nocapture`. The target: at most
//! 30 s, median at most 10 s.

use std::time::Instant;

use dca_core::controller::ControllerKind;
use host_sim::gap::diagnose::{diagnose, Options};
use host_sim::gap::measure::{gap, replays};
use host_sim::gap::run::Run;
use host_sim::gap::validation::{cases, check_scenario, fit_scenario, rig_log};
use host_sim::gap::{calibrate, grey_box};
use host_sim::model::effects::Effects;
use host_sim::model::plant::Plant;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

#[test]
#[ignore]
fn one_diagnosis_on_one_core() {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool");
    let base = Plant::nominal();
    let opts = Options::default();
    let (mut total, mut new) = (Vec::new(), Vec::new());
    for (i, c) in cases().iter().enumerate() {
        let seed = 100 + 2 * i as u64;
        let fit_log = rig_log(fit_scenario(), ControllerKind::MpcEso, &c.effects, seed);
        let check_log = rig_log(check_scenario(), ControllerKind::Pid, &c.effects, seed + 1);
        let (t_all, t_new) = pool.install(|| {
            let fit = vec![Run::new("fit.csv".into(), fit_log.clone())];
            let check = vec![Run::new("check.csv".into(), check_log.clone())];
            let t0 = Instant::now();
            let sims = replays(&fit, &base, &Effects::NONE, opts.dt_s);
            let cal = calibrate::fit(&fit, &sims, &base, opts.dt_s).expect("a map");
            let _ = gap(&check, &base, &cal.effects, opts.dt_s);
            let gb = grey_box::fit(&fit, &base, opts.dt_s).expect("replays");
            let _ = gap(&check, &base, &gb.effects, opts.dt_s);
            let _ = gap(&fit, &base, &gb.effects, opts.dt_s);
            let t_new = t0.elapsed().as_secs_f64();
            let t0 = Instant::now();
            let (d, _) = diagnose(fit, check, &base, &opts);
            let t_all = t0.elapsed().as_secs_f64();
            println!("| {} | {} | {t_all:.1} | {t_new:.1} |", c.name, d.verdict);
            (t_all, t_new)
        });
        total.push(t_all);
        new.push(t_new);
    }
    let max = total.iter().cloned().fold(0.0, f64::max);
    let max_new = new.iter().cloned().fold(0.0, f64::max);
    println!(
        "one core, {} cases: diagnosis median {:.1} s, max {max:.1} s; of it the two new candidates median {:.1} s, max {max_new:.1} s",
        total.len(),
        median(&mut total),
        median(&mut new)
    );
    assert!(max <= 30.0 && median(&mut total) <= 10.0);
}

//! `host-sim bench`: speed of the simulator and of the gap diagnosis, measured
//! side by side in one run.
//!
//! Timing on a shared machine is noisy: every figure is the best of several
//! repetitions, and the table reports ratios (real-time factors, the distance
//! to the RK4 floor, the speed-up of a batch on every core) measured in the
//! same process.

use std::hint::black_box;
use std::time::Instant;

use dca_app::settings::BOARD_DT_S;
use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use rayon::prelude::*;

use crate::gap::diagnose::{diagnose, Options};
use crate::gap::measure::{gap, replays};
use crate::gap::run::Run;
use crate::gap::stats::median;
use crate::gap::validation::{cases, check_scenario, fit_scenario, rig_log, suite_logs};
use crate::gap::{calibrate, grey_box};
use crate::model::effects::{EffectKind, Effects};
use crate::model::hose::grnn::{GrnnHose, NEWTON_STEP_TOL_PAPS};
use crate::model::plant::{HoseModel, Plant, NOMINAL_DT_S};
use crate::model::scenario::Scenario;
use crate::model::sensors::SensorMode;
use crate::sim::{run, RunSpec};

/// One line of the benchmark table.
#[derive(Clone, Debug)]
pub struct BenchRow {
    /// What was measured.
    pub what: String,
    /// The figure.
    pub value: f64,
    /// Its unit.
    pub unit: &'static str,
}

fn best_of<F: FnMut() -> f64>(reps: usize, mut f: F) -> f64 {
    (0..reps).map(|_| f()).fold(f64::INFINITY, f64::min)
}

fn spec(scenario: &str, kind: ControllerKind, hose: HoseModel, dt_s: f64) -> RunSpec {
    RunSpec {
        scenario: Scenario::by_name(scenario).expect("nominal scenario"),
        controller: ControllerConfig {
            base_dt_s: BOARD_DT_S,
            ..ControllerConfig::preset(Preset::Paper, kind)
        },
        plant: Plant::new(dca_core::params::PlantParams::NOMINAL, hose),
        effects: Default::default(),
        sensors: SensorMode::Ideal,
        seed: 0,
        dt_s,
    }
}

/// Seconds of wall time for one run of `s`.
fn time_run(s: &RunSpec) -> f64 {
    let t0 = Instant::now();
    black_box(run(s).expect("run"));
    t0.elapsed().as_secs_f64()
}

fn row(what: impl Into<String>, value: f64, unit: &'static str) -> BenchRow {
    BenchRow {
        what: what.into(),
        value,
        unit,
    }
}

/// Run the benchmarks; `reps` repetitions of each (best kept).
pub fn bench(reps: usize) -> Vec<BenchRow> {
    let reps = reps.max(1);
    let (mut rows, floor) = plant_rows(reps);
    rows.extend(run_rows(reps, floor));
    rows.extend(memory_rows(reps));
    rows.push(gap_row());
    rows.push(batch_row(reps));
    rows
}

/// One derivative evaluation and one RK4 step of the nominal plant on a
/// moving state, and the real-time factor they bound (returned as well).
fn plant_rows(reps: usize) -> (Vec<BenchRow>, f64) {
    let plant = Plant::nominal();
    let x0 = plant.initial_state(0.0);
    let n = 200_000;
    let deriv_s = best_of(reps, || {
        let mut x = x0;
        let t0 = Instant::now();
        let mut acc = 0.0;
        for i in 0..n {
            x.xo_m = 1e-9 * i as f64;
            acc += black_box(plant.derivative(black_box(&x), 0.05, 300.0))[4];
        }
        black_box(acc);
        t0.elapsed().as_secs_f64() / n as f64
    });
    let step_s = best_of(reps, || {
        let mut x = x0;
        let t0 = Instant::now();
        for _ in 0..n {
            plant.step(black_box(&mut x), 0.01, 300.0, NOMINAL_DT_S);
        }
        black_box(x);
        t0.elapsed().as_secs_f64() / n as f64
    });
    let floor = NOMINAL_DT_S / (4.0 * deriv_s);
    let rows = vec![
        row(
            "nominal plant: one derivative evaluation",
            deriv_s * 1e9,
            "ns",
        ),
        row("nominal plant: one RK4 step", step_s * 1e9, "ns"),
        row(
            "RK4 floor at dt = 1e-4 s (4 derivatives a step only)",
            floor,
            "x real time",
        ),
    ];
    (rows, floor)
}

/// Real-time factors of whole runs: the plant alone, with MPC-ESO (and its
/// share of the RK4 `floor`), the GRNN plant with MPC-ESO.
fn run_rows(reps: usize, floor: f64) -> Vec<BenchRow> {
    let mut rows = Vec::new();
    let ol = spec(
        "openloop",
        ControllerKind::MpcEso,
        HoseModel::Nonlinear,
        NOMINAL_DT_S,
    );
    let t = best_of(reps, || time_run(&ol));
    rows.push(row(
        "plant only (openloop, 4 s, dt 1e-4, logging)",
        ol.scenario.duration_s() / t,
        "x real time",
    ));
    let cl = spec(
        "stepload",
        ControllerKind::MpcEso,
        HoseModel::Nonlinear,
        NOMINAL_DT_S,
    );
    let t = best_of(reps, || time_run(&cl));
    let rtf = cl.scenario.duration_s() / t;
    rows.push(row(
        "nominal plant + MPC-ESO (stepload, 10 s, dt 1e-4), one core",
        rtf,
        "x real time",
    ));
    rows.push(row(
        "  share of the RK4 floor reached",
        rtf / floor * 100.0,
        "%",
    ));
    if let Some(grnn) = HoseModel::by_name("grnn") {
        let g = spec("stepload", ControllerKind::MpcEso, grnn, 2e-4);
        let t = best_of(reps, || time_run(&g));
        rows.push(row(
            "grnn plant + MPC-ESO (stepload, 10 s, dt 2e-4), one core",
            g.scenario.duration_s() / t,
            "x real time",
        ));
    }
    rows
}

/// The grnn-memory plant with MPC-ESO on stepload: its evaluator
/// ([`crate::model::hose::local`], mostly Taylor steps from each line's last
/// exact evaluation) and solve (Newton to
/// [`MEMORY_NEWTON_TOL_PAPS`](crate::model::hose::grnn::MEMORY_NEWTON_TOL_PAPS)
/// from a predicted start) against the same with every evaluation summed, and
/// against the former evaluator (grid-binned `Truncated`, the same bound) with
/// the former solve (to [`NEWTON_STEP_TOL_PAPS`] from the last solution), run
/// after run in one process: real-time factors, speed-ups and the work per
/// plant step.
fn memory_rows(reps: usize) -> Vec<BenchRow> {
    let new = spec(
        "stepload",
        ControllerKind::MpcEso,
        HoseModel::GrnnMemory,
        2e-4,
    );
    let net = GrnnHose::shipped_memory_grnn();
    let with_hose = |h: GrnnHose| {
        let mut s = new.clone();
        s.plant = Plant::with_grnn_hose(
            dca_core::params::PlantParams::NOMINAL,
            std::sync::Arc::new(h),
        );
        s
    };
    let summed = with_hose(
        GrnnHose::from_memory(&net, "every evaluation summed")
            .expect("memory inputs")
            .with_taylor_steps(false),
    );
    let old = with_hose(
        GrnnHose::from_memory_truncated(&net, "former")
            .expect("memory inputs")
            .with_newton(NEWTON_STEP_TOL_PAPS, false),
    );
    let d = new.scenario.duration_s();
    let (mut t_new, mut t_summed, mut t_old) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    for _ in 0..reps.min(3) {
        t_old = t_old.min(time_run(&old));
        t_summed = t_summed.min(time_run(&summed));
        t_new = t_new.min(time_run(&new));
    }
    let mut rows = vec![
        row(
            "grnn-memory plant + MPC-ESO (stepload, 10 s, dt 2e-4), one core",
            d / t_new,
            "x real time",
        ),
        row(
            "  the same with every GRNN evaluation summed (no Taylor steps)",
            d / t_summed,
            "x real time",
        ),
        row(
            "  the same with the former evaluator (grid-binned Truncated) and solve",
            d / t_old,
            "x real time",
        ),
        row(
            "  speed-up over every evaluation summed, same run",
            t_summed / t_new,
            "x",
        ),
        row(
            "  speed-up over the former evaluator and solve, same run",
            t_old / t_new,
            "x",
        ),
    ];
    rows.extend(memory_work_rows(&new));
    rows
}

/// The work per plant step of the grnn-memory plant of `s`, counted on the
/// plant stepped open loop (`openloop`; a run clones its plant, so the closed
/// loop's counters are not visible).
fn memory_work_rows(s: &RunSpec) -> Vec<BenchRow> {
    let plant = &s.plant;
    let ol = Scenario::by_name("openloop").expect("nominal scenario");
    let mut x = plant.initial_state(ol.load_n(0.0));
    let n_steps = ol.n_steps(s.dt_s);
    for k in 0..n_steps {
        let t = crate::model::scenario::tick_time_s(k, s.dt_s);
        plant.step(&mut x, ol.v_cmd_mps(t).unwrap_or(0.0), ol.load_n(t), s.dt_s);
    }
    black_box(x);
    let steps = n_steps as f64;
    let w = plant.grnn_eval_stats().unwrap_or_default();
    let (solves, iterations) = plant.grnn_solver_stats().unwrap_or_default();
    let exact = w.evals.saturating_sub(w.taylor).max(1) as f64;
    vec![
        row(
            "  GRNN evaluations per plant step (openloop, 8 Newton solves a step)",
            iterations as f64 / steps,
            "",
        ),
        row(
            "  of them Taylor steps from the last exact evaluation",
            100.0 * w.taylor as f64 / w.evals.max(1) as f64,
            "%",
        ),
        row(
            "  kernel evaluations (exp) per exact evaluation",
            w.kernels as f64 / exact,
            "",
        ),
        row(
            "  list rebuilds per 1000 exact evaluations",
            1e3 * w.rebuilds as f64 / exact,
            "",
        ),
        row(
            "  training samples visited per list rebuild",
            w.visited as f64 / w.rebuilds.max(1) as f64,
            "",
        ),
        row(
            "  Newton iterations per solve",
            iterations as f64 / solves.max(1) as f64,
            "",
        ),
    ]
}

/// One gap diagnosis of two 10 s runs (one fit, one check) on one core.
fn gap_row() -> BenchRow {
    let mut e = Effects::NONE;
    e.set(EffectKind::Friction, Some(&[20.0, 30.0, 2e-3]));
    let fit = rig_log(fit_scenario(), ControllerKind::MpcEso, &e, 1);
    let check = rig_log(check_scenario(), ControllerKind::Pid, &e, 2);
    let one = one_thread();
    let t0 = Instant::now();
    let (d, _) = one.install(|| {
        diagnose(
            vec![Run::new("fit".into(), fit.clone())],
            vec![Run::new("check".into(), check.clone())],
            &Plant::nominal(),
            &Options::default(),
        )
    });
    let t = t0.elapsed().as_secs_f64();
    row(
        format!(
            "gap diagnosis, two 10 s runs, large friction (verdict {}, pair search {}), one core",
            d.verdict,
            if d.combined.is_some() {
                "ran"
            } else {
                "skipped"
            }
        ),
        t,
        "s",
    )
}

/// One whole diagnosis of two 10 s runs (one fit, one check) on one core for
/// every case of the validation suite (the logs are the suite's, with its
/// seeds), and the share of it that the two fitted-map candidates
/// (`sensor_calibration` and `parameters`: their fits on the fit run, their
/// gaps on the check and fit runs) take when timed alone. A row per case, then
/// the median and the longest. Minutes long; a measurement, never a check:
/// beside other work on a shared machine the figures grow by half or more.
pub fn gap_suite_rows() -> Vec<BenchRow> {
    let one = one_thread();
    let base = Plant::nominal();
    let opts = Options::default();
    let (mut rows, mut all, mut maps) = (Vec::new(), Vec::new(), Vec::new());
    let cases = cases();
    for (i, c) in cases.iter().enumerate() {
        let (fit_log, check_log) = suite_logs(i, c);
        let fit = vec![Run::new("fit.csv".into(), fit_log)];
        let check = vec![Run::new("check.csv".into(), check_log)];
        let (t_all, t_maps, verdict) = one.install(|| {
            let t0 = Instant::now();
            let sims = replays(&fit, &base, &Effects::NONE, opts.dt_s);
            if let Some(cal) = calibrate::fit(&fit, &sims, &base, opts.dt_s) {
                black_box(gap(&check, &base, &cal.effects, opts.dt_s));
            }
            if let Some(gb) = grey_box::fit(&fit, &base, opts.dt_s) {
                black_box(gap(&check, &base, &gb.effects, opts.dt_s));
                black_box(gap(&fit, &base, &gb.effects, opts.dt_s));
            }
            let t_maps = t0.elapsed().as_secs_f64();
            let t0 = Instant::now();
            let (d, _) = diagnose(fit, check, &base, &opts);
            (t0.elapsed().as_secs_f64(), t_maps, d.verdict.to_string())
        });
        eprintln!("[{}/{}] {}: {t_all:.1} s", i + 1, cases.len(), c.name);
        rows.push(row(
            format!("gap diagnosis, one core: {} (verdict {verdict})", c.name),
            t_all,
            "s",
        ));
        all.push(t_all);
        maps.push(t_maps);
    }
    let n = all.len();
    rows.push(row(
        format!("gap diagnosis, one core, {n} cases: median"),
        median(&all),
        "s",
    ));
    rows.push(row(
        format!("gap diagnosis, one core, {n} cases: longest"),
        all.iter().copied().fold(0.0, f64::max),
        "s",
    ));
    rows.push(row(
        "  of it the two fitted-map candidates alone: median",
        median(&maps),
        "s",
    ));
    rows.push(row(
        "  of it the two fitted-map candidates alone: longest",
        maps.iter().copied().fold(0.0, f64::max),
        "s",
    ));
    rows
}

/// A rayon pool of one thread: what "on one core" means in the rows.
fn one_thread() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool")
}

/// A batch of 16 runs on one thread against every thread.
fn batch_row(reps: usize) -> BenchRow {
    let batch: Vec<RunSpec> = (0..16)
        .map(|i| {
            let mut s = spec(
                "step",
                ControllerKind::ALL[i % 4],
                HoseModel::Nonlinear,
                NOMINAL_DT_S,
            );
            s.sensors = SensorMode::Realistic;
            s.seed = i as u64;
            s
        })
        .collect();
    let one = one_thread();
    let t1 = best_of(reps, || {
        one.install(|| {
            let t0 = Instant::now();
            batch.par_iter().for_each(|s| {
                black_box(run(s).expect("run"));
            });
            t0.elapsed().as_secs_f64()
        })
    });
    let tn = best_of(reps, || {
        let t0 = Instant::now();
        batch.par_iter().for_each(|s| {
            black_box(run(s).expect("run"));
        });
        t0.elapsed().as_secs_f64()
    });
    row(
        format!(
            "batch of 16 runs: speed-up on {} threads over 1",
            rayon::current_num_threads()
        ),
        t1 / tn,
        "x",
    )
}

/// The table as text.
pub fn table(rows: &[BenchRow]) -> String {
    let w = rows.iter().map(|r| r.what.len()).max().unwrap_or(0);
    rows.iter()
        .map(|r| format!("{:w$}  {:>10.1} {}\n", r.what, r.value, r.unit))
        .collect()
}

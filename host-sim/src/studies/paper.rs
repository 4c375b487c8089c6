//! `host-sim paper`: the paper's simulation experiments, side by side with
//! the reference numbers (docs/model.md section 10) and the paper's Tables 3-4,
//! with a Markdown report and figures like the paper's Figs. 16 and 18-25.
//!
//! Runs the four closed-loop scenarios for MPC-ESO, MPC, PID and fuzzy PID
//! (ideal sensors, nominal plant), and beyond the paper the constrained
//! MPC-ESO with its own preset `limit`, and the open-loop scenario with and
//! without the hose, in parallel on every core.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use dca_core::params::PlantParams;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::io::files::{self, PathError};
use crate::io::plot::{self, Panel, PlotError, Series};
use crate::io::runlog::LogError;
use crate::model::plant::{HoseModel, Plant};
use crate::model::scenario::Scenario;
use crate::model::sensors::SensorMode;
use crate::sim::metrics::Metrics;
use crate::sim::request::{log_meta, trace_metrics};
use crate::sim::{run, Row, RunSpec, SimError, Trace};

/// Closed-loop scenarios of the comparison.
pub const SCENARIOS: [&str; 4] = ["step", "sine", "stepload", "sineload"];

/// Options of the paper job.
#[derive(Clone, Debug)]
pub struct PaperOptions {
    /// Report directory (created).
    pub out_dir: PathBuf,
    /// Controller preset.
    pub preset: Preset,
    /// Also write every run's log into `out_dir/logs`.
    pub write_logs: bool,
    /// Show a progress bar.
    pub progress: bool,
    /// The rig's physical parameters (`--plant`; nominal by default). The
    /// controllers keep their nominal design model.
    pub rig: PlantParams,
}

/// One metric of the comparison table.
#[derive(Clone, Debug)]
pub struct TableRow {
    /// Metric name.
    pub label: &'static str,
    /// Unit.
    pub unit: &'static str,
    /// Our value per controller, in [`ControllerKind::ALL`] order.
    pub ours: [Option<f64>; 5],
    /// docs/model.md section 10 reference for MPC-ESO, MPC, PID ("paper" preset only).
    pub spec: [Option<f64>; 3],
    /// The paper's Tables 3-4 for MPC-ESO, MPC, PID.
    pub paper: [Option<f64>; 3],
}

impl TableRow {
    /// Largest relative deviation of ours from the section 10 reference (ignoring
    /// references below `floor` in absolute value, where rounding dominates).
    pub fn max_rel_dev(&self, floor: f64) -> Option<f64> {
        self.ours[..3]
            .iter()
            .zip(self.spec.iter())
            .filter_map(|(o, s)| match (o, s) {
                (Some(o), Some(s)) if s.abs() >= floor => Some(((o - s) / s).abs()),
                _ => None,
            })
            .reduce(f64::max)
    }
}

/// Why the job failed.
#[derive(Debug, thiserror::Error)]
pub enum PaperError {
    /// A run was refused or diverged.
    #[error("{scenario}/{who}: {error}")]
    Run {
        /// Scenario name.
        scenario: String,
        /// Controller or hose name.
        who: String,
        /// Why.
        error: SimError,
    },
    /// A directory or the report could not be written.
    #[error(transparent)]
    File(#[from] PathError),
    /// A run log could not be written.
    #[error(transparent)]
    Log(#[from] LogError),
    /// A figure could not be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// Everything the job produced.
#[derive(Clone, Debug)]
pub struct PaperResult {
    /// The comparison table.
    pub table: Vec<TableRow>,
    /// Metrics per (scenario, controller).
    pub metrics: BTreeMap<(String, String), Metrics>,
    /// The Markdown report.
    pub report: PathBuf,
}

type Key = (String, String);
/// The runs of the job by (scenario, controller or hose).
pub type Runs = BTreeMap<Key, (RunSpec, Trace)>;

/// The preset a controller runs with in the comparison: the job's, except
/// the constrained MPC-ESO, which is beyond the paper and always runs its own
/// tuning `limit`.
pub fn preset_of(kind: ControllerKind, preset: Preset) -> Preset {
    match kind {
        ControllerKind::CmpcEso => Preset::Limit,
        _ => preset,
    }
}

fn spec_for(scenario: &str, kind: ControllerKind, preset: Preset, rig: &PlantParams) -> RunSpec {
    RunSpec {
        scenario: Scenario::by_name(scenario).expect("nominal scenario"),
        controller: ControllerConfig::preset(preset_of(kind, preset), kind),
        plant: Plant::new(*rig, HoseModel::Nonlinear),
        effects: Default::default(),
        sensors: SensorMode::Ideal,
        seed: 0,
        dt_s: 1e-4,
    }
}

/// Run all experiments (in parallel) on the nominal rig and return the
/// traces by (scenario, controller).
pub fn run_all(preset: Preset, progress: bool) -> Result<Runs, PaperError> {
    run_all_on(preset, &PlantParams::NOMINAL, progress)
}

/// Run all experiments (in parallel) on the rig `rig` and return the traces
/// by (scenario, controller).
pub fn run_all_on(preset: Preset, rig: &PlantParams, progress: bool) -> Result<Runs, PaperError> {
    let mut jobs: Vec<(Key, RunSpec)> = Vec::new();
    for sc in SCENARIOS {
        for kind in ControllerKind::ALL {
            jobs.push((
                (sc.to_string(), kind.name().to_string()),
                spec_for(sc, kind, preset, rig),
            ));
        }
    }
    for hose in [HoseModel::Nonlinear, HoseModel::Rigid] {
        let mut spec = spec_for("openloop", ControllerKind::MpcEso, preset, rig);
        spec.plant = Plant::new(*rig, hose);
        jobs.push((("openloop".into(), hose.name().to_string()), spec));
    }
    let bar = if progress {
        ProgressBar::new(jobs.len() as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} runs {msg}",
        )
        .expect("valid template"),
    );
    let out: Result<Runs, PaperError> = jobs
        .into_par_iter()
        .map(|(key, spec)| {
            let trace = run(&spec).map_err(|error| PaperError::Run {
                scenario: key.0.clone(),
                who: key.1.clone(),
                error,
            })?;
            bar.inc(1);
            bar.set_message(format!("{} {}", key.0, key.1));
            Ok((key, (spec, trace)))
        })
        .collect();
    bar.finish_and_clear();
    out
}

fn m<'a>(ms: &'a BTreeMap<Key, Metrics>, sc: &str, kind: ControllerKind) -> Option<&'a Metrics> {
    ms.get(&(sc.to_string(), kind.name().to_string()))
}

/// The comparison table of section 10 from the metrics of all runs.
pub fn table(ms: &BTreeMap<Key, Metrics>, preset: Preset) -> Vec<TableRow> {
    let spec_ok = preset == Preset::Paper;
    let row = |label,
               unit,
               sc: &str,
               f: &dyn Fn(&Metrics) -> Option<f64>,
               spec: [f64; 3],
               paper: [Option<f64>; 3]| TableRow {
        label,
        unit,
        ours: ControllerKind::ALL.map(|k| m(ms, sc, k).and_then(f)),
        spec: if spec_ok { spec.map(Some) } else { [None; 3] },
        paper,
    };
    let load4 = |x: &Metrics| x.load.first().cloned();
    vec![
        row(
            "rise time 10-90 %",
            "s",
            "step",
            &|x| x.rise_time_s,
            [0.75, 0.89, 0.55],
            [Some(0.75), Some(1.2), Some(3.1)],
        ),
        row(
            "steady-state error 3-4 s",
            "mm",
            "step",
            &|x| x.sse_mm,
            [0.003, 0.010, 0.141],
            [Some(0.0), Some(0.0), Some(0.12)],
        ),
        row(
            "mean square error 3-4 s",
            "mm^2",
            "step",
            &|x| x.mse_mm2,
            [0.0000, 0.0002, 0.020],
            [Some(0.0065), Some(0.01), Some(0.69)],
        ),
        row(
            "ISE 0-6 s",
            "mm^2 s",
            "step",
            &|x| Some(x.ise_mm2s),
            [820.0, 583.0, 408.0],
            [None; 3],
        ),
        row(
            "load deviation (800 N step)",
            "% of 50 mm",
            "stepload",
            &|x| load4(x).map(|l| l.deviation_pct),
            [4.02, 4.03, 3.74],
            [Some(2.82), Some(5.9), Some(9.12)],
        ),
        row(
            "load settling (1 mm band)",
            "s",
            "stepload",
            &|x| load4(x).map(|l| l.settling_s),
            [0.27, 0.63, 0.35],
            [Some(0.65), Some(1.2), Some(2.1)],
        ),
        row(
            "RMSE t >= 4 s (step load)",
            "mm",
            "stepload",
            &|x| x.rmse_after_4_mm,
            [0.38, 0.56, 0.43],
            [Some(0.81), Some(1.64), Some(2.2)],
        ),
        row(
            "sine command RMSE t >= 2 s",
            "mm",
            "sine",
            &|x| x.rmse_after_2_mm,
            [10.5, 11.4, 8.0],
            [None; 3],
        ),
        row(
            "sine load RMSE t >= 4 s",
            "mm",
            "sineload",
            &|x| x.rmse_after_4_mm,
            [0.22, 0.35, 0.31],
            [None; 3],
        ),
    ]
}

fn fmt_opt(v: Option<f64>) -> String {
    match v {
        None => "-".into(),
        Some(v) if v != 0.0 && v.abs() < 0.01 => format!("{v:.4}"),
        Some(v) if v.abs() < 10.0 => format!("{v:.3}"),
        Some(v) => format!("{v:.1}"),
    }
}

/// The table as Markdown (also readable as plain text).
pub fn table_markdown(rows: &[TableRow]) -> String {
    let mut s = String::new();
    s.push_str("| metric | unit | MPC-ESO ours / ref / paper | MPC ours / ref / paper | PID ours / ref / paper | fuzzy PID ours | beyond the paper: cmpc-eso (limit) |\n");
    s.push_str("|---|---|---|---|---|---|---|\n");
    for r in rows {
        let cell = |i: usize| {
            format!(
                "{} / {} / {}",
                fmt_opt(r.ours[i]),
                fmt_opt(r.spec[i]),
                fmt_opt(r.paper[i])
            )
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} |",
            r.label,
            r.unit,
            cell(0),
            cell(1),
            cell(2),
            fmt_opt(r.ours[3]),
            fmt_opt(r.ours[4])
        );
    }
    s
}

fn series(tr: &Trace, f: impl Fn(&Row) -> f64) -> Vec<(f64, f64)> {
    tr.rows.iter().map(|r| (r.t_s, f(r))).collect()
}

fn get<'a>(runs: &'a Runs, sc: &str, who: &str) -> Option<&'a Trace> {
    runs.get(&(sc.to_string(), who.to_string())).map(|(_, t)| t)
}

fn controller_panel(
    runs: &Runs,
    sc: &str,
    title: &str,
    y_label: &str,
    f: &dyn Fn(&Row) -> f64,
    with_ref: bool,
) -> Panel {
    let mut p = Panel::new(title, "t [s]", y_label);
    for kind in ControllerKind::ALL {
        if let Some(t) = get(runs, sc, kind.name()) {
            p = p.with(Series::line(kind.name(), series(t, f)));
        }
    }
    if with_ref {
        if let Some(t) = get(runs, sc, "mpc-eso") {
            p = p.with(Series::dashed("reference", series(t, |r| r.ref_m * 1e3)));
        }
    }
    p
}

fn figures(runs: &Runs, dir: &Path) -> Result<Vec<(String, String)>, PlotError> {
    let mut figs = Vec::new();
    let mut save = |name: &str, caption: &str, panels: Vec<Panel>| -> Result<(), PlotError> {
        plot::save(&dir.join(name), &panels, 1000, 260)?;
        figs.push((name.to_string(), caption.to_string()));
        Ok(())
    };
    let pos = |r: &Row| r.meas.xo_m * 1e3;
    let err = |r: &Row| (r.ref_m - r.meas.xo_m) * 1e3;
    let cmd = |r: &Row| r.vcmd_mps * 1e3;
    let p1 = |r: &Row| r.meas.p1_pa * 1e-6;
    let p2 = |r: &Row| r.meas.p2_pa * 1e-6;

    // Fig. 16: open loop with and without the hose.
    if let (Some(h), Some(r)) = (
        get(runs, "openloop", "nonlinear"),
        get(runs, "openloop", "rigid"),
    ) {
        let two = |title: &str, y: &str, f: &dyn Fn(&Row) -> f64| {
            Panel::new(title, "t [s]", y)
                .with(Series::line("with hose (nonlinear)", series(h, f)))
                .with(Series::dashed("without hose (rigid)", series(r, f)))
        };
        save(
            "fig16_openloop.png",
            "Open loop (scenario openloop) with and without the hose: the hose adds lag and a softer, slower load response (paper Fig. 16).",
            vec![
                two("Xo, actuating piston", "Xo [mm]", &pos),
                two("Xi, power piston", "Xi [mm]", &|r| r.meas.xi_m * 1e3),
                two("P1, line 1", "P1 [MPa]", &p1),
                two("P2, line 2", "P2 [MPa]", &p2),
            ],
        )?;
    }
    save(
        "fig18_step.png",
        "50 mm step: position, error and drive command (paper Fig. 18).",
        vec![
            controller_panel(runs, "step", "position", "Xo [mm]", &pos, true),
            controller_panel(runs, "step", "error", "e [mm]", &err, false),
            controller_panel(runs, "step", "drive command", "v_cmd [mm/s]", &cmd, false),
            controller_panel(runs, "step", "line-1 pressure", "P1 [MPa]", &p1, false),
        ],
    )?;
    save(
        "fig19_sine.png",
        "Sinusoidal command 0-50 mm at 0.25 Hz: tracking and error (paper Fig. 19).",
        vec![
            controller_panel(runs, "sine", "position", "Xo [mm]", &pos, true),
            controller_panel(runs, "sine", "error", "e [mm]", &err, false),
        ],
    )?;
    save(
        "fig20_21_stepload.png",
        "50 mm command, load 0 -> 800 N at 4 s -> 400 N at 7 s: position, error, command and pressures (paper Figs. 20-21).",
        vec![
            controller_panel(runs, "stepload", "position", "Xo [mm]", &pos, true),
            controller_panel(runs, "stepload", "error", "e [mm]", &err, false),
            controller_panel(runs, "stepload", "drive command", "v_cmd [mm/s]", &cmd, false),
            controller_panel(runs, "stepload", "line-1 pressure", "P1 [MPa]", &p1, false),
            controller_panel(runs, "stepload", "line-2 pressure", "P2 [MPa]", &p2, false),
        ],
    )?;
    save(
        "fig23_24_sineload.png",
        "50 mm command under the load 200 sin(pi t) + 400 N: position, error and command (paper Figs. 23-24).",
        vec![
            controller_panel(runs, "sineload", "position", "Xo [mm]", &pos, true),
            controller_panel(runs, "sineload", "error", "e [mm]", &err, false),
            controller_panel(runs, "sineload", "drive command", "v_cmd [mm/s]", &cmd, false),
        ],
    )?;
    for (sc, name, fig) in [
        ("stepload", "fig22_eso_stepload.png", "22"),
        ("sineload", "fig25_eso_sineload.png", "25"),
    ] {
        if let Some(t) = get(runs, sc, "mpc-eso") {
            let z = |i: usize| move |r: &Row| r.eso.map(|z| z[i] as f64).unwrap_or(f64::NAN);
            let panels = vec![
                Panel::new("displacement", "t [s]", "[mm]")
                    .with(Series::line("true Xo", series(t, |r| r.truth.xo_m * 1e3)))
                    .with(Series::dashed("ESO z1", series(t, move |r| z(0)(r) * 1e3))),
                Panel::new("speed", "t [s]", "[mm/s]")
                    .with(Series::line("true vo", series(t, |r| r.truth.vo_mps * 1e3)))
                    .with(Series::dashed("ESO z2", series(t, move |r| z(1)(r) * 1e3))),
                Panel::new("total disturbance (acceleration)", "t [s]", "[m/s^2]")
                    .with(Series::line("true dvo/dt", series(t, |r| r.ao_true_mps2)))
                    .with(Series::dashed("ESO z3", series(t, z(2)))),
            ];
            save(
                name,
                &format!("MPC-ESO, scenario {sc}: ESO estimates against the true states (paper Fig. {fig})."),
                panels,
            )?;
        }
    }
    Ok(figs)
}

/// Run the job: simulations, table, figures, report.
pub fn run_paper(opts: &PaperOptions) -> Result<PaperResult, PaperError> {
    files::create_dir_all(&opts.out_dir)?;
    let started = std::time::Instant::now();
    let runs = run_all_on(opts.preset, &opts.rig, opts.progress)?;
    let sim_s = started.elapsed().as_secs_f64();
    let metrics: BTreeMap<Key, Metrics> = runs
        .iter()
        .filter(|(k, _)| k.0 != "openloop")
        .map(|(k, (spec, tr))| (k.clone(), trace_metrics(tr, &spec.scenario)))
        .collect();
    if opts.write_logs {
        let logs = opts.out_dir.join("logs");
        files::create_dir_all(&logs)?;
        for ((sc, who), (spec, tr)) in &runs {
            let mut meta = log_meta(spec);
            meta.push(("config", opts.preset.name().to_string()));
            tr.to_runlog(&meta)
                .write(&logs.join(format!("{sc}-{who}.csv")))?;
        }
    }
    let rows = table(&metrics, opts.preset);
    let figs = figures(&runs, &opts.out_dir)?;
    let mut md = String::new();
    let _ = writeln!(md, "# DCA: the paper's simulation experiments\n");
    let _ = writeln!(
        md,
        "Configuration `{}`, {} (docs/model.md sections 2-4, nonlinear hose, RK4 at 1e-4 s), ideal sensors; \
         {} runs in {:.1} s on {} threads. Generated by `host-sim paper` {}.\n",
        opts.preset.name(),
        if opts.rig == PlantParams::NOMINAL {
            "nominal plant"
        } else {
            "plant off nominal (below)"
        },
        runs.len(),
        sim_s,
        rayon::current_num_threads(),
        env!("CARGO_PKG_VERSION")
    );
    let off = crate::model::params::columns(&opts.rig, &[], false);
    if !off.is_empty() {
        let kv: Vec<String> = off.iter().map(|(k, v)| format!("`{k}={v}`")).collect();
        let _ = writeln!(
            md,
            "**Rig off nominal** (`--plant`): {}. The controllers keep their nominal design model, \
             so the references below are for the nominal rig.\n",
            kv.join(", ")
        );
    }
    let _ = writeln!(
        md,
        "## Metrics against docs/model.md section 10 and the paper's Tables 3-4\n"
    );
    let _ = writeln!(
        md,
        "Each cell: this implementation / the reference implementation of docs/model.md section 10 / the paper. \
         Metric definitions: docs/model.md section 8. The paper's PID numbers cannot be reproduced with its own \
         gains (docs/model.md section 11, item 17); its fuzzy PID has no published numbers.\n"
    );
    md.push_str(&table_markdown(&rows));
    let _ = writeln!(md, "\n## Figures\n");
    for (file, caption) in &figs {
        let _ = writeln!(md, "![{caption}]({file})\n\n*{caption}*\n");
    }
    let report = opts.out_dir.join("report.md");
    files::write(&report, md)?;
    Ok(PaperResult {
        table: rows,
        metrics,
        report,
    })
}

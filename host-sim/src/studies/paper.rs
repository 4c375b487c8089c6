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

use dca_app::settings::BOARD_DT_S;
use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use dca_core::eso::EsoParams;
use dca_core::params::PlantParams;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::io::files::{self, PathError};
use crate::io::plot::{self, Panel, PlotError, Series, Style};
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
        // At the board's control tick, as every command of host-sim.
        controller: ControllerConfig {
            base_dt_s: BOARD_DT_S,
            ..ControllerConfig::preset(preset_of(kind, preset), kind)
        },
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

/// The time axis of every time plot.
const TIME: &str = "time t [s]";

/// The order in which the controllers' traces are drawn (the last on top),
/// and how: PID wide and beneath, the fuzzy PID (which follows it closely)
/// dashed over it, so that both stay visible where they coincide. The
/// colour stays each controller's on every panel.
const DRAWN: [(ControllerKind, Style, u32); 5] = [
    (ControllerKind::Pid, Style::Line, 5),
    (ControllerKind::Mpc, Style::Line, 2),
    (ControllerKind::MpcEso, Style::Line, 2),
    (ControllerKind::CmpcEso, Style::Line, 2),
    (ControllerKind::FuzzyPid, Style::Dashed, 2),
];

/// The legend name of a controller's trace.
fn legend_name(kind: ControllerKind) -> String {
    match kind {
        ControllerKind::CmpcEso => format!("{} (limit)", kind.name()),
        _ => kind.name().to_string(),
    }
}

fn controller_panel(
    runs: &Runs,
    sc: &str,
    title: &str,
    y_label: &str,
    f: &dyn Fn(&Row) -> f64,
    with_ref: bool,
) -> Panel {
    let mut p = Panel::new(title, TIME, y_label);
    if with_ref {
        if let Some(t) = get(runs, sc, "mpc-eso") {
            p = p.with(
                Series::dashed("reference", series(t, |r| r.ref_m * 1e3))
                    .colored(7)
                    .width(1),
            );
        }
    }
    for (kind, style, width) in DRAWN {
        if let Some(t) = get(runs, sc, kind.name()) {
            let colour = ControllerKind::ALL
                .iter()
                .position(|k| *k == kind)
                .unwrap_or(0);
            p = p.with(
                Series::line(legend_name(kind), series(t, f))
                    .styled(style)
                    .width(width)
                    .colored(colour),
            );
        }
    }
    p
}

/// One figure of the report.
struct Figure {
    file: &'static str,
    caption: String,
    panels: Vec<Panel>,
}

/// The ESO's total disturbance as its own linear dynamics see the truth:
/// the true acceleration less `b0 v_cmd`, through
/// `b3 / (s^3 + beta1 s^2 + b2 s + b3)` with the linear-zone gains
/// `b2 = beta2 / delta^(1 - alpha1)`, `b3 = beta3 / delta^(1 - alpha2)`
/// (docs/model.md section 6.5; in that zone z3 obeys exactly this transfer
/// function of the disturbance). RK4 over the 1 ms rows, the input held
/// between rows.
fn through_eso(tr: &Trace, eso: &EsoParams) -> Vec<(f64, f64)> {
    let (b1, b2, b3) = linear_gains(eso);
    let f = |x: [f64; 3], a: f64| [x[1], x[2], b3 * (a - x[0]) - b2 * x[1] - b1 * x[2]];
    let mut x = [0.0; 3];
    let mut out = Vec::with_capacity(tr.rows.len());
    let mut prev_t = tr.rows.first().map_or(0.0, |r| r.t_s);
    for r in &tr.rows {
        let a = r.ao_true_mps2 - eso.b0 * r.vcmd_mps;
        let h = r.t_s - prev_t;
        if h > 0.0 {
            let add = |x: [f64; 3], k: [f64; 3], s: f64| [0, 1, 2].map(|i| x[i] + s * k[i]);
            let k1 = f(x, a);
            let k2 = f(add(x, k1, h / 2.0), a);
            let k3 = f(add(x, k2, h / 2.0), a);
            let k4 = f(add(x, k3, h), a);
            x = [0, 1, 2].map(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
        }
        prev_t = r.t_s;
        out.push((r.t_s, x[0]));
    }
    out
}

/// The ESO's gains in its linear zone (|e| <= delta): beta1, beta2', beta3'.
fn linear_gains(eso: &EsoParams) -> (f64, f64, f64) {
    (
        eso.beta1,
        eso.beta2 / eso.delta_m.powf(1.0 - eso.alpha1),
        eso.beta3 / eso.delta_m.powf(1.0 - eso.alpha2),
    )
}

/// The poles of `s^3 + a s^2 + b s + c` (real root by bisection, the other
/// two from the quotient), as text: "-1.55 and -14.2 +- 34.2j".
fn cubic_poles(a: f64, b: f64, c: f64) -> String {
    let p = |s: f64| ((s + a) * s + b) * s + c;
    // With a, b, c > 0 the real root is negative and above -(a + b + c + 1).
    let (mut lo, mut hi) = (-(a + b.abs() + c.abs() + 1.0), 0.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if p(mid) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let r = 0.5 * (lo + hi);
    // s^3 + a s^2 + b s + c = (s - r)(s^2 + q1 s + q0)
    let q1 = a + r;
    let q0 = b + r * q1;
    let disc = q1 * q1 - 4.0 * q0;
    if disc < 0.0 {
        format!(
            "{} and {} +- {}j rad/s",
            sig3(r),
            sig3(-q1 / 2.0),
            sig3((-disc).sqrt() / 2.0)
        )
    } else {
        let d = disc.sqrt();
        format!(
            "{}, {} and {} rad/s",
            sig3(r),
            sig3((-q1 - d) / 2.0),
            sig3((-q1 + d) / 2.0)
        )
    }
}

/// `v` to 3 significant digits (-1.553 -> "-1.55", 34.17 -> "34.2").
fn sig3(v: f64) -> String {
    let v: f64 = format!("{v:.2e}").parse().unwrap_or(v);
    let mag = if v == 0.0 {
        0
    } else {
        v.abs().log10().floor() as i32
    };
    format!("{v:.*}", (2 - mag).max(0) as usize)
}

fn eso_figure(runs: &Runs, sc: &str, file: &'static str, fig: &str) -> Option<Figure> {
    let (spec, t) = runs.get(&(sc.to_string(), "mpc-eso".to_string()))?;
    let eso = &spec.controller.eso;
    let z = |i: usize| move |r: &Row| r.eso.map(|z| f64::from(z[i])).unwrap_or(f64::NAN);
    let seen = through_eso(t, eso);
    let z3 = series(t, z(2));
    let peak = |v: &[(f64, f64)]| v.iter().map(|p| p.1.abs()).fold(0.0, f64::max);
    let true_acc = series(t, |r| r.ao_true_mps2);
    let apart = z3
        .iter()
        .zip(&seen)
        .map(|(a, b)| (a.1 - b.1).abs())
        .filter(|d| d.is_finite())
        .fold(0.0, f64::max);
    let (b1, b2, b3) = linear_gains(eso);
    let caption = format!(
        "MPC-ESO, scenario {sc}: ESO estimates against the true states (paper Fig. {fig}). \
         The ESO has no model of the plant (docs/model.md sections 6.4-6.5): its z3, the total disturbance, \
         estimates the piston's acceleration less b0 v_cmd only within the observer's bandwidth (linear-zone \
         poles {poles}, h = {h} s). The true acceleration (third panel, up to {peak_a:.1} m/s^2) is mostly the \
         piston ringing on the oil's and the hoses' compliance after each step of load or command, far faster \
         than that, and it integrates to almost no change of speed; so z3 stays within {peak_z:.2} m/s^2, and a \
         static load leaves it at 0 (the MPC's integral action removes that offset). The last panel compares z3 \
         with the true acceleration passed through the observer's own linear dynamics, \
         b3'/(s^3 + b1 s^2 + b2' s + b3') with b1 = {b1} 1/s, b2' = {b2:.0} 1/s^2, b3' = {b3:.0} 1/s^3: \
         they differ by at most {apart:.3} m/s^2.",
        poles = cubic_poles(b1, b2, b3),
        h = eso.h_s,
        peak_a = peak(&true_acc),
        peak_z = peak(&z3),
    );
    let panels = vec![
        Panel::new("displacement", TIME, "position Xo [mm]")
            .with(Series::line("true Xo", series(t, |r| r.truth.xo_m * 1e3)).width(3))
            .with(Series::dashed("ESO z1", series(t, move |r| z(0)(r) * 1e3))),
        Panel::new("speed", TIME, "speed vo [mm/s]")
            .with(Series::line("true vo", series(t, |r| r.truth.vo_mps * 1e3)).width(1))
            .with(Series::dashed("ESO z2", series(t, move |r| z(1)(r) * 1e3))),
        Panel::new(
            "acceleration: the truth and the ESO's total disturbance",
            TIME,
            "acceleration [m/s^2]",
        )
        .with(Series::line("true dvo/dt", true_acc).width(1))
        .with(Series::dashed("ESO z3", z3.clone())),
        Panel::new(
            "total disturbance, within the observer's bandwidth",
            TIME,
            "acceleration [m/s^2]",
        )
        .with(
            Series::line(
                "true dvo/dt - b0 v_cmd through the ESO's linear dynamics",
                seen,
            )
            .width(3)
            .colored(2),
        )
        .with(Series::dashed("ESO z3", z3).colored(1)),
    ];
    Some(Figure {
        file,
        caption,
        panels,
    })
}

/// The report's figures (without drawing them).
fn figure_list(runs: &Runs) -> Vec<Figure> {
    let mut figs = Vec::new();
    let pos = |r: &Row| r.meas.xo_m * 1e3;
    let err = |r: &Row| (r.ref_m - r.meas.xo_m) * 1e3;
    let cmd = |r: &Row| r.vcmd_mps * 1e3;
    let p1 = |r: &Row| r.meas.p1_pa * 1e-6;
    let p2 = |r: &Row| r.meas.p2_pa * 1e-6;
    const XO: &str = "position Xo [mm]";
    const XI: &str = "position Xi [mm]";
    const E: &str = "error r - Xo [mm]";
    const V: &str = "command v_cmd [mm/s]";
    const P1: &str = "pressure P1 [MPa]";
    const P2: &str = "pressure P2 [MPa]";

    // Fig. 16: open loop with and without the hose.
    if let (Some(h), Some(r)) = (
        get(runs, "openloop", "nonlinear"),
        get(runs, "openloop", "rigid"),
    ) {
        let two = |title: &str, y: &str, f: &dyn Fn(&Row) -> f64| {
            Panel::new(title, TIME, y)
                .with(Series::line("with hose (nonlinear)", series(h, f)).width(3))
                .with(Series::dashed("without hose (rigid)", series(r, f)).width(1))
        };
        figs.push(Figure {
            file: "fig16_openloop.png",
            caption: "Open loop (scenario openloop) with and without the hose: the hose adds lag and a softer, slower load response (paper Fig. 16).".into(),
            panels: vec![
                two("Xo, actuating piston", XO, &pos),
                two("Xi, power piston", XI, &|r| r.meas.xi_m * 1e3),
                two("P1, line 1", P1, &p1),
                two("P2, line 2", P2, &p2),
            ],
        });
    }
    let note = " PID is drawn wide and beneath, the fuzzy PID dashed over it: where only one shows, they coincide.";
    figs.push(Figure {
        file: "fig18_step.png",
        caption: format!("50 mm step: position, error and drive command (paper Fig. 18).{note}"),
        panels: vec![
            controller_panel(runs, "step", "position", XO, &pos, true),
            controller_panel(runs, "step", "error", E, &err, false),
            controller_panel(runs, "step", "drive command", V, &cmd, false),
            controller_panel(runs, "step", "line-1 pressure", P1, &p1, false),
        ],
    });
    figs.push(Figure {
        file: "fig19_sine.png",
        caption: format!(
            "Sinusoidal command 0-50 mm at 0.25 Hz: tracking and error (paper Fig. 19).{note}"
        ),
        panels: vec![
            controller_panel(runs, "sine", "position", XO, &pos, true),
            controller_panel(runs, "sine", "error", E, &err, false),
        ],
    });
    figs.push(Figure {
        file: "fig20_21_stepload.png",
        caption: format!("50 mm command, load 0 -> 800 N at 4 s -> 400 N at 7 s: position, error, command and pressures (paper Figs. 20-21).{note}"),
        panels: vec![
            controller_panel(runs, "stepload", "position", XO, &pos, true),
            controller_panel(runs, "stepload", "error", E, &err, false),
            controller_panel(runs, "stepload", "drive command", V, &cmd, false),
            controller_panel(runs, "stepload", "line-1 pressure", P1, &p1, false),
            controller_panel(runs, "stepload", "line-2 pressure", P2, &p2, false),
        ],
    });
    figs.push(Figure {
        file: "fig23_24_sineload.png",
        caption: format!("50 mm command under the load 200 sin(pi t) + 400 N: position, error and command (paper Figs. 23-24).{note}"),
        panels: vec![
            controller_panel(runs, "sineload", "position", XO, &pos, true),
            controller_panel(runs, "sineload", "error", E, &err, false),
            controller_panel(runs, "sineload", "drive command", V, &cmd, false),
        ],
    });
    for (sc, file, fig) in [
        ("stepload", "fig22_eso_stepload.png", "22"),
        ("sineload", "fig25_eso_sineload.png", "25"),
    ] {
        figs.extend(eso_figure(runs, sc, file, fig));
    }
    figs
}

fn figures(runs: &Runs, dir: &Path) -> Result<Vec<(String, String)>, PlotError> {
    let mut out = Vec::new();
    for f in figure_list(runs) {
        plot::save(&dir.join(f.file), &f.panels, 1000, 260)?;
        out.push((f.file.to_string(), f.caption));
    }
    Ok(out)
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
        "Configuration `{}`, {} (docs/model.md sections 2-4, nonlinear hose, RK4 at 1e-4 s), the controllers at the board's 1 ms tick, ideal sensors; \
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Every run of the job, with an empty trace (the figures' layout only).
    fn empty_runs() -> Runs {
        let mut runs = Runs::new();
        let trace = |sc: &str, who: &str| Trace {
            scenario: sc.into(),
            controller: who.into(),
            rows: Vec::new(),
        };
        for sc in SCENARIOS {
            for kind in ControllerKind::ALL {
                let spec = spec_for(sc, kind, Preset::Paper, &PlantParams::NOMINAL);
                runs.insert(
                    (sc.into(), kind.name().into()),
                    (spec, trace(sc, kind.name())),
                );
            }
        }
        for hose in ["nonlinear", "rigid"] {
            let spec = spec_for(
                "openloop",
                ControllerKind::MpcEso,
                Preset::Paper,
                &PlantParams::NOMINAL,
            );
            runs.insert(
                ("openloop".into(), hose.into()),
                (spec, trace("openloop", hose)),
            );
        }
        runs
    }

    /// Every axis of every figure names a quantity and its unit: `what [unit]`.
    #[test]
    fn every_axis_has_a_quantity_and_a_unit() {
        let figs = figure_list(&empty_runs());
        assert_eq!(figs.len(), 7, "figures 16, 18, 19, 20-21, 22, 23-24, 25");
        for f in &figs {
            for p in &f.panels {
                for label in [&p.x_label, &p.y_label] {
                    let (what, unit) = label
                        .strip_suffix(']')
                        .and_then(|l| l.rsplit_once(" ["))
                        .unwrap_or_else(|| {
                            panic!("{}, {}: `{label}` has no unit", f.file, p.title)
                        });
                    assert!(
                        what.chars().any(char::is_alphabetic) && !unit.is_empty(),
                        "{}, {}: `{label}`",
                        f.file,
                        p.title
                    );
                }
            }
        }
    }

    /// The observer's linear-zone poles as docs/model.md section 6.5 gives them.
    #[test]
    fn the_eso_poles_of_section_6_5() {
        let (b1, b2, b3) = linear_gains(&EsoParams::PAPER);
        assert_eq!(cubic_poles(b1, b2, b3), "-1.55 and -14.2 +- 34.2j rad/s");
        assert_eq!(cubic_poles(6.0, 11.0, 6.0), "-1.00, -3.00 and -2.00 rad/s");
        assert_eq!(sig3(-1.553), "-1.55");
        assert_eq!(sig3(2127.4), "2130");
        assert_eq!(sig3(34.17), "34.2");
    }

    /// Fig. 22's claim: the ESO's z3 is the true acceleration (less b0 v_cmd)
    /// through the observer's own linear dynamics, not the acceleration itself.
    #[test]
    fn z3_is_the_true_acceleration_through_the_eso_dynamics() {
        let spec = spec_for(
            "stepload",
            ControllerKind::MpcEso,
            Preset::Paper,
            &PlantParams::NOMINAL,
        );
        let t = run(&spec).unwrap();
        let seen = through_eso(&t, &spec.controller.eso);
        let z3: Vec<f64> = t
            .rows
            .iter()
            .map(|r| f64::from(r.eso.unwrap()[2]))
            .collect();
        let peak = |v: &mut dyn Iterator<Item = f64>| v.map(f64::abs).fold(0.0, f64::max);
        let acc = peak(&mut t.rows.iter().map(|r| r.ao_true_mps2));
        let z3_peak = peak(&mut z3.iter().copied());
        let apart = peak(&mut z3.iter().zip(&seen).map(|(a, b)| a - b.1));
        assert!(
            acc > 10.0 && z3_peak < 0.02 * acc,
            "acceleration {acc}, z3 {z3_peak}"
        );
        assert!(apart < 0.25 * z3_peak, "z3 {z3_peak}, apart {apart}");
    }
}

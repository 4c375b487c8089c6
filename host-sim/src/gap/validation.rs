//! Validation suite of the gap diagnosis: synthetic rig runs with hidden
//! effects (each effect of docs/model.md section 12 at two magnitudes, some pairs,
//! and clean runs), realistic sensors with noise, fit and check runs from
//! different scenarios and controllers. The diagnosis sees only the logs;
//! the truth stays here and scores the verdicts.
//!
//! * fit run (10 s, MPC-ESO): moves 0 -> 40 -> 10 -> 30 mm (a reversal),
//!   load 0 -> 800 N at 6 s -> 300 N at 8 s;
//! * check run (10 s, PI): 0.25 Hz sine reference 5-45 mm under a
//!   300 + 250 sin(2 pi 0.4 t) N load.
//!
//! A verdict is right when it names the hidden effect (either one for a
//! pair), or `none` for a clean run.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use super::diagnose::{diagnose, Options};
use super::diagnosis::{Diagnosis, Verdict};
use super::policy::NONE_GAP;
use super::run::Run;
use crate::io::runlog::RunLog;
use crate::model::effects::{
    CalChannel, EffectKind, Effects, GasRelaxation, HysteresisSpectrum, LeakageMap, ScrewMap,
    SensorFilter, SensorMap, ServoEnvelope,
};
use crate::model::plant::Plant;
use crate::model::scenario::{Command, Piecewise, Scenario, Signal};
use crate::model::sensors::SensorMode;
use crate::sim::{run, RunSpec};

/// One case of the suite.
#[derive(Clone, Debug)]
pub struct Case {
    /// Display name, e.g. `leakage (large)`.
    pub name: String,
    /// The hidden effects (empty: clean).
    pub truth: Vec<EffectKind>,
    /// Their parameters.
    pub effects: Effects,
}

fn case(name: &str, list: &[(EffectKind, &[f64])]) -> Case {
    let mut e = Effects::NONE;
    for (k, v) in list {
        e.set(*k, Some(v));
    }
    Case {
        name: name.to_string(),
        truth: list.iter().map(|(k, _)| *k).collect(),
        effects: e,
    }
}

/// The cases: clean runs, every effect of the catalogue small and large,
/// three pairs, four rigs whose nominal parameters are off (`parameters`),
/// five sensors off their calibration (`sensor_calibration`), and effects
/// in shapes their named forms cannot take (a servo force falling with
/// speed, a hose wall with two hysteresis scales, two accumulators, a seal
/// lip that leaks only above 1 MPa, an encoder read through a moving
/// average, an LVDT with a wavy linearity error, a load cell short at high
/// loads, a screw in Hertzian contact). Each case's noise seeds follow from
/// its place ([`suite_logs`]): new cases go last.
pub fn cases() -> Vec<Case> {
    let mut all = named_cases();
    all.extend(pair_cases());
    all.extend(parameter_cases());
    all.extend(general_family_cases());
    all.extend(calibration_cases());
    // Last: a case added keeps the others' noise seeds.
    all.push(hertzian_screw_case());
    all
}

/// Two clean rigs, then every effect of the catalogue small and large.
fn named_cases() -> Vec<Case> {
    use EffectKind::*;
    vec![
        case("clean (seed a)", &[]),
        case("clean (seed b)", &[]),
        case("leakage (small)", &[(Leakage, &[3e-14])]),
        case("leakage (large)", &[(Leakage, &[1.5e-13])]),
        case("friction (small)", &[(Friction, &[20.0, 30.0, 2e-3])]),
        case("friction (large)", &[(Friction, &[60.0, 90.0, 2e-3])]),
        case("backlash (small)", &[(Backlash, &[60e-6, 1e8])]),
        case("backlash (large)", &[(Backlash, &[200e-6, 2e7])]),
        case("air (small)", &[(Air, &[0.003])]),
        case("air (large)", &[(Air, &[0.015])]),
        case("sensor_delay (small)", &[(SensorDelay, &[3e-3, 1e-3, 0.0])]),
        case(
            "sensor_delay (large)",
            &[(SensorDelay, &[8e-3, 4e-3, 2e-3])],
        ),
        case("motor_limit (small)", &[(MotorLimit, &[900.0, 300.0, 0.1])]),
        case(
            "motor_limit (large)",
            &[(MotorLimit, &[1200.0, 400.0, 0.05])],
        ),
        case(
            "hose_hysteresis (small)",
            &[(HoseHysteresis, &[1e-13, 0.0, 5e4])],
        ),
        case(
            "hose_hysteresis (large)",
            &[(HoseHysteresis, &[2e-13, 0.5, 1e5])],
        ),
        case(
            "accumulator_thermal (small)",
            &[(AccumulatorThermal, &[15.0])],
        ),
        case(
            "accumulator_thermal (large)",
            &[(AccumulatorThermal, &[3.0])],
        ),
    ]
}

/// Three pairs of effects.
fn pair_cases() -> Vec<Case> {
    use EffectKind::*;
    vec![
        case(
            "leakage + friction",
            &[(Leakage, &[1e-13]), (Friction, &[40.0, 60.0, 2e-3])],
        ),
        case(
            "air + sensor_delay",
            &[(Air, &[0.008]), (SensorDelay, &[5e-3, 2e-3, 0.0])],
        ),
        case(
            "backlash + accumulator_thermal",
            &[(Backlash, &[150e-6, 2e7]), (AccumulatorThermal, &[4.0])],
        ),
    ]
}

/// Four rigs whose nominal parameters are off (`parameters`).
fn parameter_cases() -> Vec<Case> {
    use EffectKind::*;
    vec![
        // Ratios in the order of `ParameterRatios`: m, beta_e, hose wall
        // compliance, viscous damping, servo time constant, precharge, areas.
        case(
            "parameters: bulk modulus -25 %",
            &[(Parameters, &[1.0, 0.75])],
        ),
        case("parameters: mass +30 %", &[(Parameters, &[1.3])]),
        case(
            "parameters: hose wall 1.7x softer",
            &[(Parameters, &[1.0, 1.0, 1.7])],
        ),
        case(
            "parameters: servo time constant +50 %",
            &[(Parameters, &[1.0, 1.0, 1.0, 1.0, 1.5])],
        ),
    ]
}

/// Shapes the named forms cannot take: their general families.
fn general_family_cases() -> Vec<Case> {
    use EffectKind::*;
    vec![
        Case {
            name: "motor_limit (torque-speed curve)".into(),
            truth: vec![MotorLimit],
            effects: Effects {
                servo_envelope: Some(ServoEnvelope {
                    mass_eq_kg: 150.0,
                    force_n: [1100.0, 1100.0, 900.0, 600.0, 300.0, 0.0],
                    accel_max_mps2: None,
                    speed_loop: None,
                    command_map: None,
                }),
                ..Effects::NONE
            },
        },
        Case {
            name: "hose_hysteresis (two scales)".into(),
            truth: vec![HoseHysteresis],
            effects: Effects {
                hose_spectrum: Some(HysteresisSpectrum::plays([1.5e-13, 0.0, 0.0, 0.0, 3e-13])),
                ..Effects::NONE
            },
        },
        Case {
            // Two heat paths of the accumulator gas (a fast one to a foam
            // filling, a slow one to the shell) and a total beyond the
            // thermal n - 1 (a creeping bladder): no single time constant.
            name: "accumulator_thermal (two heat paths)".into(),
            truth: vec![AccumulatorThermal],
            effects: Effects {
                gas_relaxation: Some(GasRelaxation {
                    weights: [0.0, 0.25, 0.0, 0.0, 0.35, 0.0],
                }),
                ..Effects::NONE
            },
        },
        Case {
            // An accumulator whose gas spring gives more, and faster, than
            // heat exchange alone allows: within 0.1 s its index falls from
            // 1.4 to 0.8 (a bladder whose folds yield), then it creeps over
            // half a minute. The named form relaxes by n - 1 = 0.4 at most,
            // over one time constant.
            name: "accumulator_thermal (yielding, creeping bladder)".into(),
            truth: vec![AccumulatorThermal],
            effects: Effects {
                gas_relaxation: Some(GasRelaxation {
                    weights: [0.6, 0.0, 0.0, 0.0, 0.0, 0.3],
                }),
                ..Effects::NONE
            },
        },
        Case {
            // A seal lip that opens above 1 MPa: no leakage below, then a
            // steep rise (the named form's power law cannot bend so).
            name: "leakage (seal lip opening above 1 MPa)".into(),
            truth: vec![Leakage],
            effects: Effects {
                leakage_map: Some(LeakageMap {
                    q_m3ps: [0.0, 0.0, 0.0, 1.5e-7, 6e-7],
                    g_m3pspa: 0.0,
                }),
                ..Effects::NONE
            },
        },
        Case {
            // The board averages the encoder over 5 ms (taps 0 to 4 ms):
            // the named form filters only the LVDT and the pressures.
            name: "sensor_delay (encoder, 5 ms moving average)".into(),
            truth: vec![SensorDelay],
            effects: Effects {
                sensor_filter: Some(SensorFilter {
                    channel: CalChannel::Xi,
                    weights: [1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                }),
                ..Effects::NONE
            },
        },
        Case {
            // A wavy linearity error, +0.2 mm at 15 mm and -0.2 mm at 35 mm
            // (odd about mid-stroke: no quadratic takes it).
            name: "sensor_calibration (LVDT wavy, +-0.2 mm)".into(),
            truth: vec![SensorCalibration],
            effects: Effects {
                sensor_map: Some(SensorMap {
                    channel: CalChannel::Xo,
                    knots_si: [-0.010, 0.005, 0.015, 0.025, 0.035, 0.045],
                    readings_si: [-0.010, 0.005, 0.0152, 0.025, 0.0348, 0.045],
                }),
                ..Effects::NONE
            },
        },
        Case {
            // A load cell whose reading falls behind the load as it rises:
            // 8 % short at 1000 N, quadratic in the load (the named force
            // map is affine).
            name: "sensor_calibration (force sensor, 8 % short at 1000 N)".into(),
            truth: vec![SensorCalibration],
            effects: Effects {
                sensor_map: Some(SensorMap {
                    channel: CalChannel::Ft,
                    knots_si: [-200.0, 200.0, 400.0, 600.0, 800.0, 1000.0],
                    readings_si: [-203.2, 196.8, 387.2, 571.2, 748.8, 920.0],
                }),
                ..Effects::NONE
            },
        },
    ]
}

/// Five sensors off their calibration, in the named form.
fn calibration_cases() -> Vec<Case> {
    use EffectKind::*;
    vec![
        // channel (0 xo, 1 xi, 2 p1, 3 p2, 4 ft), gain, offset (SI), quad.
        case(
            "sensor_calibration: LVDT gain 1.03",
            &[(SensorCalibration, &[0.0, 1.03, 0.0, 0.0])],
        ),
        case(
            "sensor_calibration: LVDT gain 0.98, offset 0.3 mm",
            &[(SensorCalibration, &[0.0, 0.98, 3e-4, 0.0])],
        ),
        case(
            "sensor_calibration: p1 gain 1.04",
            &[(SensorCalibration, &[2.0, 1.04, 0.0, 0.0])],
        ),
        case(
            "sensor_calibration: p2 offset +0.1 MPa",
            &[(SensorCalibration, &[3.0, 1.0, 1e5, 0.0])],
        ),
        case(
            "sensor_calibration: force gain 0.93",
            &[(SensorCalibration, &[4.0, 0.93, 0.0, 0.0])],
        ),
    ]
}

/// A screw in Hertzian contact (the suite's last case).
fn hertzian_screw_case() -> Case {
    use EffectKind::*;
    Case {
        // A screw whose balls touch the races in Hertzian contacts: the
        // deflection grows as F^(2/3) (20 um at 1 kN) beyond a play of
        // 60 um (the named form's stiffness is constant).
        name: "backlash (Hertzian contact)".into(),
        truth: vec![Backlash],
        effects: Effects {
            screw_map: Some(ScrewMap {
                deflection_m: [24e-6, 31.9e-6, 34.3e-6, 39.0e-6, 50e-6, 71.6e-6],
            }),
            ..Effects::NONE
        },
    }
}

/// The fit scenario: moves with a reversal, then load steps.
pub fn fit_scenario() -> Scenario {
    let steps =
        |t: Vec<f64>, v: &[f64]| Signal::Piecewise(Piecewise::constants(t, v).expect("valid"));
    Scenario::new(
        "fit-moves-loads",
        10.0,
        Command::Reference(steps(vec![2.5, 4.5], &[0.040, 0.010, 0.030])),
        steps(vec![6.0, 8.0], &[0.0, 800.0, 300.0]),
    )
}

/// The check scenario: sine tracking under a sine load.
pub fn check_scenario() -> Scenario {
    Scenario::new(
        "check-sine-sineload",
        10.0,
        Command::Reference(Signal::Cosine {
            bias: 0.025,
            amplitude: -0.020,
            omega_radps: std::f64::consts::PI / 2.0,
            t0_s: 0.0,
        }),
        Signal::Sine {
            bias: 300.0,
            amplitude: 250.0,
            omega_radps: 2.0 * std::f64::consts::PI * 0.4,
            t0_s: 0.0,
        },
    )
}

/// A synthetic rig log: `scenario` under `kind` with `effects`, realistic
/// sensors seeded with `seed`, as the diagnosis would read it from a file.
pub fn rig_log(scenario: Scenario, kind: ControllerKind, effects: &Effects, seed: u64) -> RunLog {
    rig_log_on(Plant::nominal(), scenario, kind, effects, seed)
}

/// [`rig_log`] on the plant `plant` (its parameters off the nominal ones).
pub fn rig_log_on(
    plant: Plant,
    scenario: Scenario,
    kind: ControllerKind,
    effects: &Effects,
    seed: u64,
) -> RunLog {
    let controller = ControllerConfig::preset(Preset::Paper, kind);
    rig_log_with(plant, scenario, controller, effects, seed)
}

/// [`rig_log_on`] under the controller `controller`.
pub fn rig_log_with(
    plant: Plant,
    scenario: Scenario,
    controller: ControllerConfig,
    effects: &Effects,
    seed: u64,
) -> RunLog {
    let spec = RunSpec {
        scenario,
        controller,
        plant,
        effects: *effects,
        sensors: SensorMode::Realistic,
        seed,
        dt_s: 1e-4,
    };
    let trace = run(&spec).expect("valid run");
    let mut text = Vec::new();
    trace.to_runlog(&[]).write_to(&mut text).expect("in memory");
    RunLog::parse(
        std::str::from_utf8(&text).expect("utf-8"),
        spec.scenario.name(),
    )
    .expect("own log reads back")
}

/// The result of one case.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The case.
    pub case: Case,
    /// The diagnosis.
    pub diagnosis: Diagnosis,
}

impl Outcome {
    /// The verdict names the hidden effect (or `none` for a clean run).
    pub fn right(&self) -> bool {
        if self.case.truth.is_empty() {
            self.diagnosis.verdict == Verdict::None
        } else {
            self.case
                .truth
                .iter()
                .any(|k| Verdict::Effect(*k) == self.diagnosis.verdict)
        }
    }

    /// The truth as a label.
    pub fn truth_label(&self) -> String {
        if self.case.truth.is_empty() {
            "none".into()
        } else {
            self.case
                .truth
                .iter()
                .map(|k| k.name())
                .collect::<Vec<_>>()
                .join("+")
        }
    }
}

/// Run the suite (cases in parallel): logs from [`rig_log`], then [`score`].
pub fn run_suite(cases: &[Case], opts: &Options, progress: bool) -> Vec<Outcome> {
    score(cases, suite_logs, opts, progress)
}

/// The fit and check logs [`run_suite`] diagnoses for the `i`-th case `c`
/// of [`cases`] (1 ms rows; [`RunLog::decimate`] makes the console's 10 ms
/// ones). The noise seeds follow from `i`: a case run alone keeps its
/// index, and new cases go last.
pub fn suite_logs(i: usize, c: &Case) -> (RunLog, RunLog) {
    let seed = 100 + 2 * i as u64;
    (
        rig_log(fit_scenario(), ControllerKind::MpcEso, &c.effects, seed),
        rig_log(check_scenario(), ControllerKind::Pid, &c.effects, seed + 1),
    )
}

/// Diagnose every case (in parallel) on the fit and check logs `logs(i, case)`
/// makes for it, from any source; the truth stays in the cases.
pub fn score(
    cases: &[Case],
    logs: impl Fn(usize, &Case) -> (RunLog, RunLog) + Sync,
    opts: &Options,
    progress: bool,
) -> Vec<Outcome> {
    let bar = if progress {
        ProgressBar::new(cases.len() as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("[{elapsed_precise}] {bar:30} {pos}/{len} cases {msg}")
            .expect("valid template"),
    );
    let quiet = Options {
        progress: false,
        ..opts.clone()
    };
    let out = cases
        .par_iter()
        .enumerate()
        .map(|(i, c)| {
            let (fit, check) = logs(i, c);
            let fit = vec![Run::new("fit.csv".into(), fit)];
            let check = vec![Run::new("check.csv".into(), check)];
            let (diagnosis, _) = diagnose(fit, check, &Plant::nominal(), &quiet);
            bar.inc(1);
            bar.set_message(c.name.clone());
            Outcome {
                case: c.clone(),
                diagnosis,
            }
        })
        .collect();
    bar.finish_and_clear();
    out
}

/// Summary numbers of a suite run.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Right verdicts among single-effect cases, and their number.
    pub single: (usize, usize),
    /// Right verdicts among clean cases, and their number.
    pub clean: (usize, usize),
    /// Right verdicts among pairs, and their number.
    pub pairs: (usize, usize),
    /// Median check-run shrink over right verdicts naming an effect whose
    /// check runs show a gap beyond the noise.
    pub median_check_shrink: f64,
    /// Smallest check-run shrink over the same verdicts.
    pub min_check_shrink: f64,
    /// Right verdicts naming an effect whose check runs show no gap beyond
    /// the noise (the check scenario does not excite the effect).
    pub unexcited: usize,
}

impl Outcome {
    /// The check runs show a gap beyond the noise (they excite the effect).
    pub fn check_excited(&self) -> bool {
        self.diagnosis.check.before >= NONE_GAP
    }

    /// Every gap of the diagnosis (fit and check, before and after) is
    /// finite: the replay and the search ran end to end.
    pub fn gaps_finite(&self) -> bool {
        let (f, c) = (&self.diagnosis.fit, &self.diagnosis.check);
        [f.before, f.after, c.before, c.after]
            .iter()
            .all(|g| g.is_finite())
    }
}

/// Score the outcomes.
pub fn summary(out: &[Outcome]) -> Summary {
    let count = |f: &dyn Fn(&Outcome) -> bool| {
        let all: Vec<&Outcome> = out.iter().filter(|o| f(o)).collect();
        (all.iter().filter(|o| o.right()).count(), all.len())
    };
    let named = |o: &&Outcome| o.right() && !o.case.truth.is_empty();
    let mut shrinks: Vec<f64> = out
        .iter()
        .filter(named)
        .filter(|o| o.check_excited())
        .map(|o| o.diagnosis.check.shrink)
        .collect();
    let unexcited = out
        .iter()
        .filter(named)
        .filter(|o| !o.check_excited())
        .count();
    shrinks.sort_by(|a, b| a.total_cmp(b));
    Summary {
        single: count(&|o| o.case.truth.len() == 1),
        clean: count(&|o| o.case.truth.is_empty()),
        pairs: count(&|o| o.case.truth.len() == 2),
        median_check_shrink: super::stats::median(&shrinks),
        min_check_shrink: shrinks.first().copied().unwrap_or(f64::NAN),
        unexcited,
    }
}

/// Print the [`markdown`] of a suite's outcomes, save it as `target/<file>`
/// of the workspace (best effort), and score the outcomes.
pub fn publish(out: &[Outcome], file: &str) -> Summary {
    let table = markdown(out);
    println!("{table}");
    let target = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../target")
        .join(file);
    std::fs::write(&target, &table).ok();
    summary(out)
}

/// The confusion table (truth by verdict) and the per-case results, Markdown.
pub fn markdown(out: &[Outcome]) -> String {
    let mut verdicts: Vec<String> = EffectKind::ALL
        .iter()
        .map(|k| k.name().to_string())
        .collect();
    verdicts.push("none".into());
    verdicts.push("unexplained".into());
    let mut table: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    for o in out {
        *table
            .entry(o.truth_label())
            .or_default()
            .entry(o.diagnosis.verdict.to_string())
            .or_default() += 1;
    }
    let mut s = String::new();
    let _ = writeln!(s, "| truth \\ verdict | {} |", verdicts.join(" | "));
    let _ = writeln!(s, "|---|{}", "---|".repeat(verdicts.len()));
    for (truth, row) in &table {
        let cells: Vec<String> = verdicts
            .iter()
            .map(|v| {
                row.get(v)
                    .map(|n| n.to_string())
                    .unwrap_or_else(|| ".".into())
            })
            .collect();
        let _ = writeln!(s, "| {truth} | {} |", cells.join(" | "));
    }
    let _ = writeln!(s, "\n| case | verdict | form | right | fit before -> after | check before -> after | check shrink | time [s] |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for o in out {
        let d = &o.diagnosis;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.2} -> {:.2} | {:.2} -> {:.2} | {:.0} % | {:.1} |",
            o.case.name,
            d.verdict,
            d.form.as_deref().unwrap_or("-"),
            if o.right() { "yes" } else { "**no**" },
            d.fit.before,
            d.fit.after,
            d.check.before,
            d.check.after,
            d.check.shrink * 100.0,
            d.elapsed_s
        );
    }
    new_candidates(&mut s, out);
    let m = summary(out);
    let _ = writeln!(
        s,
        "\nSingle effects right: {}/{}; clean runs `none`: {}/{}; pairs naming one of the two: {}/{}; \
         check-run shrink on right verdicts where the check runs show a gap: median {:.0} %, lowest {:.0} % \
         ({} right verdicts with check runs that do not excite the effect).",
        m.single.0,
        m.single.1,
        m.clean.0,
        m.clean.1,
        m.pairs.0,
        m.pairs.1,
        m.median_check_shrink * 100.0,
        m.min_check_shrink * 100.0,
        m.unexcited
    );
    s
}

/// The `parameters` and `sensor_calibration` candidates of every case, one
/// line each: what they fitted and how much they shrank the gap on the fit
/// and the check runs (so that a re-estimate absorbing a named effect, or
/// a calibration absorbing dynamics, shows whatever the verdict).
fn new_candidates(s: &mut String, out: &[Outcome]) {
    let _ = writeln!(
        s,
        "\n| case | `parameters`: ratio [95 % interval] | fit / check shrink | `sensor_calibration`: form, map | fit / check shrink |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|");
    let find = |o: &Outcome, k: EffectKind| {
        o.diagnosis
            .candidates
            .iter()
            .find(|c| c.effect == k.name())
            .cloned()
    };
    for o in out {
        let p = find(o, EffectKind::Parameters);
        let est: Vec<String> = o
            .diagnosis
            .parameters
            .iter()
            .filter(|e| !e.key.starts_with("hose.cf") && !e.key.starts_with("hose.cs"))
            .filter(|e| e.key != "aa2_m2")
            .map(|e| {
                format!(
                    "{} {:.3} [{:.3}, {:.3}]{}",
                    e.key,
                    e.ratio,
                    e.ci95[0] / e.nominal,
                    e.ci95[1] / e.nominal,
                    if e.at_bound { " (at bound)" } else { "" }
                )
            })
            .collect();
        let c = find(o, EffectKind::SensorCalibration);
        let map = c.as_ref().map_or("-".to_string(), |c| {
            let kv: Vec<String> = c
                .params
                .iter()
                .filter(|(k, _)| k.as_str() != "channel")
                .map(|(k, v)| format!("{k} {v:.4}"))
                .collect();
            format!("{}: {}", c.form, kv.join(", "))
        });
        let shr = |c: &Option<super::diagnosis::Candidate>| {
            c.as_ref().map_or("-".to_string(), |c| {
                format!(
                    "{:.0} % / {:.0} %",
                    c.fit_shrink * 100.0,
                    c.check_shrink * 100.0
                )
            })
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            o.case.name,
            if est.is_empty() {
                "none".to_string()
            } else {
                est.join("; ")
            },
            shr(&p),
            map,
            shr(&c)
        );
    }
}

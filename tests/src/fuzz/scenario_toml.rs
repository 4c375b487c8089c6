//! Scenario files: [`ScenarioFile::load_str`] on arbitrary text (the input as
//! UTF-8, invalid sequences replaced), then what `host-sim run` does with an
//! accepted file short of simulating it.
//!
//! Invariants:
//! * no panic, no hang;
//! * errors name the file, and a line that exists in the text;
//! * an accepted scenario has a finite duration in (0, 3600] s, and its
//!   command and load are finite at the start, the end, a few instants
//!   between, and on both sides of every switching instant;
//! * its `[controller]` table names a known preset and kind (the loader
//!   checks them) and passes the configuration checks of
//!   [`mod@super::config_toml`];
//! * its `[plant.params]` give a rig whose every parameter lies within its
//!   plausible range (`host_sim::model::params::check_plausible`);
//! * its `[plant]` hose and sensor names either resolve or are refused, and
//!   effects that pass `Effects::validate` give a finite rig: the rest state
//!   and a few plant steps under a small command. (Found here: `validate`
//!   once asked only for finite, non-negative values, so a leakage
//!   conductance of 1 or an air `kappa` of 0 passed and the rig diverged;
//!   regressions `leakage-conductance-1.toml`, `air-kappa-zero.toml`.)

use std::sync::OnceLock;

use dca_core::params::PlantParams;
use host_sim::model::effects::Effects;
use host_sim::model::params::check_plausible;
use host_sim::model::plant::{HoseModel, Plant, NOMINAL_DT_S};
use host_sim::model::rig::Rig;
use host_sim::model::scenario::{tick_time_s, Command, Signal};
use host_sim::model::sensors::SensorMode;
use host_sim::sim::config::{LoadedScenario, ScenarioFile};

use super::config_toml::{check_config, check_file_error};
use super::text;

const FILE: &str = "fuzz.toml";

/// Most switching instants probed per signal.
const MAX_SWITCHES: usize = 16;

/// The switching instants of `s` (nested ones included), at most
/// [`MAX_SWITCHES`].
fn switches(s: &Signal, out: &mut Vec<f64>) {
    if let Signal::Piecewise(p) = s {
        for t in p.thresholds_s() {
            if out.len() < MAX_SWITCHES {
                out.push(*t);
            }
        }
        for piece in p.pieces() {
            switches(piece, out);
        }
    }
}

/// `s` is finite over a scenario of `d` s and `n` ticks of the nominal step.
fn check_signal(name: &str, s: &Signal, d: f64, n: u64) {
    let mut times: Vec<f64> = vec![0.0, 0.25 * d, 0.5 * d, 0.75 * d, d];
    // The last tick a run at the nominal step evaluates.
    times.push(tick_time_s(n.saturating_sub(1), NOMINAL_DT_S));
    let mut sw = Vec::new();
    switches(s, &mut sw);
    for t in sw {
        times.extend([t, t.next_down()]);
    }
    for t in times {
        if !(0.0..=d).contains(&t) {
            continue;
        }
        let v = s.value(t);
        assert!(v.is_finite(), "{name} is {v} at t = {t} s: {s:?}");
    }
}

fn nominal_plant() -> &'static Plant {
    static PLANT: OnceLock<Plant> = OnceLock::new();
    PLANT.get_or_init(|| Plant::new(PlantParams::NOMINAL, HoseModel::Nonlinear))
}

/// Effects that validate give a finite rig at rest and over a few steps.
fn check_effects(e: &Effects) {
    if e.validate().is_err() {
        return;
    }
    let rig = match Rig::new(nominal_plant().clone(), *e) {
        Ok(r) => r,
        Err(err) => panic!("validated effects refused by the nominal rig: {err}"),
    };
    let mut s = rig.initial_state(0.0);
    let mut steps = 0;
    while s.is_finite() && steps < 20 {
        rig.step(&mut s, 0.02, 0.0, NOMINAL_DT_S);
        steps += 1;
    }
    assert!(
        s.is_finite(),
        "validated effects make the rig diverge after {steps} steps: {e:?}: {s:?}"
    );
}

fn check_loaded(ls: &LoadedScenario, text: &str) {
    let sc = &ls.scenario;
    let d = sc.duration_s();
    assert!(d.is_finite() && d > 0.0 && d <= 3600.0, "duration {d}");
    let n = sc.n_steps(NOMINAL_DT_S);
    match sc.command() {
        Command::Reference(r) => check_signal("reference", r, d, n),
        Command::OpenLoop(v) => check_signal("open_loop", v, d, n),
    }
    check_signal("load", sc.load(), d, n);
    if let Some(c) = &ls.controller {
        assert!(
            c.preset(FILE).is_ok(),
            "the loader let an unknown preset pass"
        );
        assert!(
            c.kind(FILE).is_ok(),
            "the loader let an unknown controller pass"
        );
        check_config(c, FILE, text);
    }
    let p = &ls.plant;
    let rig = p
        .plant_params(FILE)
        .expect("the loader checked [plant.params]");
    if let Err(e) = check_plausible(&rig) {
        panic!("the loader let an implausible rig pass: {e}");
    }
    if let Some(h) = &p.hose {
        if let Some(m) = HoseModel::by_name(h) {
            assert_eq!(m.name(), h);
        }
    }
    if let Some(s) = &p.sensors {
        if let Some(m) = SensorMode::by_name(s) {
            assert_eq!(m.name(), s);
        }
    }
    if let Some(e) = &p.effects {
        check_effects(e);
    }
}

/// The scenario harness; see the module documentation.
pub fn scenario_toml(data: &[u8]) {
    let text = text(data);
    match ScenarioFile::load_str(&text, FILE, "fuzz") {
        Ok(ls) => check_loaded(&ls, &text),
        Err(e) => check_file_error(&e, FILE, &text),
    }
}

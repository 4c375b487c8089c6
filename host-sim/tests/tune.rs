//! `host-sim tune` (docs/interfaces.md section 8): the tuned settings are
//! written once and read back as they were measured, the search never
//! returns worse than where it started, the console script holds the same
//! numbers, a rig on which nothing is safe is refused with the reason, and
//! one that limit-cycles at rest with the preset is tuned out of it, also
//! where its own design model looks as good a start as the nominal one.

use dca_app::settings::Settings;
use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use dca_core::params::PlantParams;
use host_sim::model::effects::Effects;
use host_sim::model::plant::HoseModel;
use host_sim::model::sensors::SensorMode;
use host_sim::sim::config::{ConfigFile, RigFile};
use host_sim::studies::tune::{cost, tune, Robust, TuneError, TuneSetup, DESIGN_SHARES};

fn setup(params: PlantParams, evals: u64) -> TuneSetup {
    let mut base = ControllerConfig::preset(Preset::Limit, ControllerKind::CmpcEso);
    base.base_dt_s = 1e-3;
    TuneSetup {
        rig: RigFile {
            params,
            effects: Effects::default(),
            alternatives: Vec::new(),
        },
        hose: HoseModel::Nonlinear,
        base,
        preset: Preset::Limit,
        sensors: SensorMode::Realistic,
        seed: 0,
        max_evals: evals,
        robust: Robust {
            draws: 1,
            fraction: 0.05,
        },
        progress: false,
    }
}

#[test]
fn tuned_settings_read_back_and_beat_the_start() {
    // A heavier load than nominal: the design model follows the rig, as far
    // as it does no harm.
    let mut rig = PlantParams::NOMINAL;
    rig.m_kg = 60.0;
    let s = setup(rig, 8);
    let t = tune(&s, "test rig").unwrap();
    // The file is the configuration measured.
    let mut back = ConfigFile::parse_str(&t.config_text, "tuned.toml")
        .unwrap()
        .resolve(ControllerKind::CmpcEso, "tuned.toml")
        .unwrap();
    back.base_dt_s = 1e-3;
    assert_eq!(back, t.config);
    // The design model is the rig's, or moved toward the nominal one by a
    // share the tune tries (where the rig's own costs more at the start).
    let m = t.config.plant.m_kg;
    assert!(
        DESIGN_SHARES
            .iter()
            .any(|s| (m / (50.0 * 1.2f64.powf(*s)) - 1.0).abs() < 1e-8),
        "{m}"
    );
    // The script sets the same values, in order, then stores.
    let sets: Vec<&str> = t
        .script_text
        .lines()
        .filter(|l| l.starts_with("set "))
        .collect();
    assert_eq!(sets.len(), t.changed.len());
    let mut board = Settings::preset(Preset::Limit, ControllerKind::CmpcEso);
    for line in &sets {
        let mut w = line.split_whitespace().skip(1);
        let (path, v) = (w.next().unwrap(), w.next().unwrap());
        board = board.with(path, v.parse().unwrap()).unwrap().0;
    }
    board.controller.base_dt_s = 1e-3;
    assert_eq!(
        board.controller, t.config,
        "the board holds what the host ran"
    );
    assert_eq!(t.script_text.lines().last(), Some("store"));
    // Never worse than the start (the nominal design on this rig).
    assert!(t.after.infeasible.is_none());
    let (before, after) = (cost(&t.before, &t.before), cost(&t.after, &t.before));
    assert!(after <= before, "{after} > {before}");
}

#[test]
fn a_rig_with_no_safe_setting_is_refused() {
    // The rig's stroke ends at 30 mm: the paper's 50 mm step cannot be
    // reached whatever the settings (the error never settles).
    let mut rig = PlantParams::NOMINAL;
    rig.x_max_m = 0.03;
    match tune(&setup(rig, 4), "short rig") {
        Err(TuneError::Refused { reason, candidates }) => {
            assert!(reason.contains("on the rig itself: step"), "{reason}");
            // The candidates are listed (the report's table), each refused,
            // the starting settings last.
            assert_eq!(
                candidates.last().map(|c| (c.origin, c.changed)),
                Some(("starting settings", 0))
            );
            assert!(
                candidates.iter().all(|c| c.worst.is_err()),
                "{candidates:?}"
            );
        }
        other => panic!("expected a refusal, got {:?}", other.map(|t| t.changed)),
    }
}

#[test]
fn a_rig_that_limit_cycles_at_rest_is_tuned_out_of_it() {
    // Smaller actuating areas: AP1/AA1 1.9 against the model's 1.2. With the
    // preset the load rings about its held position at the pressures of no
    // load (the hose at its softest) and settles under load; only a faster
    // observer ended it on such rigs (docs/control.md).
    let mut rig = PlantParams::NOMINAL;
    rig.m_kg = 64.0;
    rig.ap1_m2 = 4.76e-4;
    rig.ap2_m2 = 4.28e-4;
    rig.aa1_m2 = 2.46e-4;
    rig.aa2_m2 = 1.49e-4;
    let t = tune(&setup(rig, 8), "ringing rig").unwrap();
    let held = |e: &host_sim::studies::tune::Evaluation| e.metrics[0].rmse_after_2_mm.unwrap();
    assert!(held(&t.before) > 0.5, "{} mm", held(&t.before));
    assert!(held(&t.after) < 0.1, "{} mm", held(&t.after));
    let preset = ControllerConfig::preset(Preset::Limit, ControllerKind::CmpcEso);
    assert!(
        t.config.eso.beta1 > 1.5 * preset.eso.beta1,
        "{}",
        t.config.eso.beta1
    );
}

#[test]
fn a_ringing_rig_identified_with_its_own_design_is_tuned_out_of_it_whatever_the_seed() {
    // Rig 242 of `--perturb 0.3` as the diagnosis identified it. With this
    // noise seed its own design model passes as the search's start (it costs
    // 0.9994 of the preset's there), and from there no faster observer ends
    // the cycle; from the nominal design one does. The tune kept the preset
    // (0.95 mm held) before it scanned the observer on both designs.
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/rig-242-identified.toml"
    );
    let rig = host_sim::sim::config::read_plant_file(std::path::Path::new(path)).unwrap();
    let mut s = setup(rig.params, 40);
    s.rig = rig;
    s.seed = 242;
    s.robust = Robust {
        draws: 4,
        fraction: 0.1,
    };
    let t = tune(&s, "rig 242 identified").unwrap();
    let held = |e: &host_sim::studies::tune::Evaluation| e.metrics[0].rmse_after_2_mm.unwrap();
    assert!(held(&t.before) > 0.5, "{} mm", held(&t.before));
    assert!(held(&t.after) < 0.2, "{} mm", held(&t.after));
}

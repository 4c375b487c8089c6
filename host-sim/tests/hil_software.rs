//! The HIL lockstep loop with the core in this process (no emulator needed).

use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use host_sim::hil::{run_software, setup_commands, HilError};
use host_sim::io::runlog::RunLog;
use host_sim::model::effects::Effects;
use host_sim::model::plant::Plant;
use host_sim::model::scenario::Scenario;
use host_sim::model::sensors::SensorMode;
use host_sim::sim::RunSpec;

fn spec(name: &str, cfg: ControllerConfig) -> RunSpec {
    RunSpec {
        scenario: Scenario::by_name(name).unwrap(),
        controller: cfg,
        plant: Plant::nominal(),
        sensors: SensorMode::Ideal,
        seed: 0,
        dt_s: 1e-4,
        effects: Effects::default(),
    }
}

#[test]
fn presets_set_up_with_two_commands_and_overrides_are_typed_exactly() {
    let cfg = ControllerConfig::preset(Preset::Fast, ControllerKind::Pid);
    assert_eq!(
        setup_commands(&cfg).unwrap(),
        ["controller pid", "preset fast"]
    );
    let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
    cfg.mpc_eso.rw = 40.5;
    cfg.pid.kp = 3.1;
    let cmds = setup_commands(&cfg).unwrap();
    assert_eq!(cmds[..2], ["controller mpc-eso", "preset paper"]);
    assert!(
        cmds.contains(&"set mpc_eso.rw 4.05e1".to_string()),
        "{cmds:?}"
    );
    assert!(cmds.contains(&"set pid.kp 3.1e0".to_string()), "{cmds:?}");
    // A value the console cannot type exactly is refused, not approximated.
    cfg.mpc_eso.rw = 1.0 / 3.0;
    assert!(matches!(setup_commands(&cfg), Err(HilError::Spec(_))));
    // So is a parameter the console does not offer.
    let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
    cfg.plant.m_kg = 60.0;
    assert!(matches!(setup_commands(&cfg), Err(HilError::Spec(_))));
}

#[test]
fn software_lockstep_tracks_the_step_and_writes_a_run_log() {
    let cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
    let trace = run_software(&spec("step", cfg)).unwrap();
    assert_eq!(trace.rows.len(), 6000);
    let last = trace.rows.last().unwrap();
    assert!(
        (last.sample.xo_m - 0.05).abs() < 1e-3,
        "xo = {}",
        last.sample.xo_m
    );
    assert!(trace.rows.iter().all(|r| r.reply.faults == 0));
    let mut text = Vec::new();
    trace.write_log(&mut text).unwrap();
    let log = RunLog::parse(std::str::from_utf8(&text).unwrap(), "hil.csv").unwrap();
    assert_eq!(log.len(), 6000);
    assert!((log.dt_s() - 1e-3).abs() < 1e-12);
    // Deterministic: a second run gives the same commands bit for bit.
    let again = run_software(&spec("step", cfg)).unwrap();
    assert_eq!(trace.first_difference(&again), None);
}

#[test]
fn open_loop_scenarios_are_refused() {
    let cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::Pid);
    assert!(matches!(
        run_software(&spec("openloop", cfg)),
        Err(HilError::Spec(_))
    ));
}

/// The board designs on its own nominal model: a non-nominal design model is
/// refused with a clear reason before any port is opened; a rig off nominal
/// is fine (it is simulated here).
#[test]
fn a_design_model_off_nominal_is_refused() {
    let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
    let mut s = spec("step", cfg);
    let mut rig = *s.plant.params();
    rig.m_kg = 60.0;
    s.plant = Plant::new(rig, s.plant.hose_model());
    host_sim::hil::check_board_model(&s).unwrap();
    cfg.plant.m_kg = 60.0;
    let s = spec("step", cfg);
    let e = host_sim::hil::check_board_model(&s)
        .unwrap_err()
        .to_string();
    assert!(e.contains("model.m_kg") && e.contains("nominal"), "{e}");
    let e = host_sim::hil::run_hil_serial(&s, "/dev/nonexistent", &Default::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("design model"), "{e}");
}

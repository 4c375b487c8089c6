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
    // The design model goes to the board's model.* settings ...
    let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
    cfg.plant.m_kg = 60.0;
    let cmds = setup_commands(&cfg).unwrap();
    assert!(cmds.contains(&"set model.m_kg 6e1".to_string()), "{cmds:?}");
    // ... but a parameter the console does not offer is refused.
    cfg.plant.v_dead_m3 = 2e-6;
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

/// The board designs on its settings' model.* parameters and on nominal
/// values for the rest: a design model off nominal where the board has a
/// setting is carried, elsewhere refused with a clear reason before any port
/// is opened; a rig off nominal is fine (it is simulated here).
#[test]
fn a_design_model_the_board_cannot_hold_is_refused() {
    let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
    let mut s = spec("step", cfg);
    let mut rig = *s.plant.params();
    rig.m_kg = 60.0;
    rig.v_dead_m3 = 2e-6;
    s.plant = Plant::new(rig, s.plant.hose_model());
    host_sim::hil::check_board_model(&s).unwrap();
    cfg.plant.m_kg = 60.0;
    host_sim::hil::check_board_model(&spec("step", cfg)).unwrap();
    cfg.plant.v_dead_m3 = 2e-6;
    let s = spec("step", cfg);
    let e = host_sim::hil::check_board_model(&s)
        .unwrap_err()
        .to_string();
    assert!(e.contains("v_dead_m3") && !e.contains("m_kg"), "{e}");
    let e = host_sim::hil::run_hil_serial(&s, "/dev/nonexistent", &Default::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("design model"), "{e}");
}

/// `host-sim run` predicts the board: the simulator's loop, resolved as the
/// command line resolves it (the board's 1 ms control tick by default), gives
/// the drive commands of the HIL loop (the board's `ControlLoop`, which
/// `hil --compare` checks bit for bit against the emulated firmware) to the
/// bit, for every controller and preset, with ideal and realistic sensors.
#[test]
fn run_gives_the_commands_of_the_hil_loop_for_every_controller_and_preset() {
    use host_sim::sim::request::{resolve, RunRequest};
    for kind in ControllerKind::ALL {
        for preset in Preset::ALL {
            for sensors in ["ideal", "realistic"] {
                let req = RunRequest {
                    scenario: "stepload".into(),
                    controller: Some(kind.name().into()),
                    config: Some(preset.name().into()),
                    sensors: Some(sensors.into()),
                    seed: Some(3),
                    ..RunRequest::default()
                };
                let spec = resolve(&req).unwrap();
                assert_eq!(spec.controller.base_dt_s, 1e-3);
                let sim = host_sim::sim::run(&spec).unwrap();
                let hil = run_software(&spec).unwrap();
                let what = format!("{} / {} / {sensors}", kind.name(), preset.name());
                assert_eq!(sim.rows.len(), hil.rows.len(), "{what}");
                for (s, h) in sim.rows.iter().zip(&hil.rows) {
                    assert_eq!(
                        s.vcmd_mps.to_bits(),
                        (h.reply.v_cmd_mps as f64).to_bits(),
                        "{what}: t = {} s",
                        s.t_s
                    );
                    assert_eq!(s.meas.to_sample(), h.sample, "{what}: t = {} s", s.t_s);
                }
            }
        }
    }
}

/// A finer control tick is a study's explicit choice and changes the run;
/// a tick that is not a whole number of plant steps is refused.
#[test]
fn a_finer_control_tick_is_an_option() {
    use host_sim::sim::request::{resolve, RunRequest};
    use host_sim::sim::SimError;
    let req = |tick: Option<f64>| RunRequest {
        scenario: "stepload".into(),
        controller: Some("cmpc-eso".into()),
        config: Some("limit".into()),
        control_tick_s: tick,
        ..RunRequest::default()
    };
    let board = host_sim::sim::run(&resolve(&req(None)).unwrap()).unwrap();
    let fine = host_sim::sim::run(&resolve(&req(Some(1e-4))).unwrap()).unwrap();
    assert_eq!(board.rows.len(), fine.rows.len());
    assert!(board
        .rows
        .iter()
        .zip(&fine.rows)
        .any(|(a, b)| a.vcmd_mps != b.vcmd_mps));
    let e = host_sim::sim::run(&resolve(&req(Some(1.5e-4))).unwrap()).unwrap_err();
    assert!(matches!(e, SimError::Tick { .. }), "{e}");
    assert!(e.to_string().contains("control tick"), "{e}");
}

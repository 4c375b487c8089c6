//! The controller interface: schedule, presets, input guards, property tests.

use dca_core::controller::{
    ConfigError, Controller, ControllerConfig, ControllerKind, Flags, Preset, Sample,
};
use dca_core::design::DesignError;
use proptest::prelude::*;

fn sample(xo_m: f32) -> Sample {
    Sample {
        xo_m,
        ..Sample::default()
    }
}

#[test]
fn names_round_trip() {
    for k in ControllerKind::ALL {
        assert_eq!(ControllerKind::from_name(k.name()), Some(k));
    }
    for p in Preset::ALL {
        assert_eq!(Preset::from_name(p.name()), Some(p));
    }
    assert_eq!(ControllerKind::from_name("lqr"), None);
    assert_eq!(Preset::from_name("slow"), None);
}

#[test]
fn paper_and_fast_periods() {
    let c = Controller::new(&ControllerConfig::preset(
        Preset::Paper,
        ControllerKind::MpcEso,
    ))
    .unwrap();
    assert_eq!(c.periods(), (60, 1000));
    let c = Controller::new(&ControllerConfig::preset(
        Preset::Fast,
        ControllerKind::MpcEso,
    ))
    .unwrap();
    assert_eq!(c.periods(), (10, 100));
    // The board's 1 kHz base tick.
    let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::Pid);
    cfg.base_dt_s = 1e-3;
    assert_eq!(Controller::new(&cfg).unwrap().periods(), (1, 100));
}

#[test]
fn command_is_held_between_controller_ticks() {
    let cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::Pid);
    let mut c = Controller::new(&cfg).unwrap();
    let first = c.step(&sample(0.0), 0.01).v_cmd_mps;
    assert!((first - 0.027).abs() < 1e-6);
    for _ in 1..1000 {
        // The measurement changes but no PID tick is due: the command holds.
        assert_eq!(c.step(&sample(0.005), 0.01).v_cmd_mps, first);
    }
    let next = c.step(&sample(0.005), 0.01).v_cmd_mps;
    assert_ne!(next, first);
}

#[test]
fn mpc_eso_first_move_waits_for_the_td() {
    // The TD starts at the measured position, so the first MPC tick sees no
    // error and the first move comes one MPC period later (docs/model.md 6.6).
    let cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
    let mut c = Controller::new(&cfg).unwrap();
    assert_eq!(c.step(&sample(0.0), 0.05).v_cmd_mps, 0.0);
    let mut v = 0.0;
    for _ in 1..=1000 {
        v = c.step(&sample(0.0), 0.05).v_cmd_mps;
    }
    assert!(v > 0.01, "{v}");
    let td = c.td_output().unwrap();
    assert!(td[0] > 0.01 && td[0] < 0.05, "{td:?}");
    assert!(c.eso_estimates().is_some());
}

#[test]
fn bumpless_start_from_the_measured_position() {
    let cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
    let mut c = Controller::new(&cfg).unwrap();
    let s = Sample {
        xo_m: 0.04,
        xi_m: 0.033,
        ..Sample::default()
    };
    // Holding the current position: no move at all.
    for _ in 0..5000 {
        let out = c.step(&s, 0.04);
        assert!(out.v_cmd_mps.abs() < 1e-3, "{out:?}");
    }
    assert!((c.position_command() - 0.033).abs() < 1e-3);
}

#[test]
fn invalid_configurations_are_refused() {
    let base = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
    let mut cfg = base;
    cfg.base_dt_s = 0.0;
    assert_eq!(Controller::new(&cfg).unwrap_err(), ConfigError::Schedule);
    let mut cfg = base;
    cfg.mpc_eso.np = 1;
    assert_eq!(
        Controller::new(&cfg).unwrap_err(),
        ConfigError::Design(DesignError::PredictionHorizon)
    );
    let mut cfg = base;
    cfg.eso.h_s = 1e-6; // shorter than the base tick
    assert_eq!(Controller::new(&cfg).unwrap_err(), ConfigError::Schedule);
    let mut cfg = base;
    cfg.limits.v_max_mps = -1.0;
    assert_eq!(Controller::new(&cfg).unwrap_err(), ConfigError::Limits);
    let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::Pid);
    cfg.pid.kp = f32::NAN;
    assert_eq!(Controller::new(&cfg).unwrap_err(), ConfigError::Pid);
    let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::FuzzyPid);
    cfg.fuzzy.e_span_m = 0.0;
    assert_eq!(Controller::new(&cfg).unwrap_err(), ConfigError::Pid);
    let mut cfg = base;
    cfg.td.r_mps2 = 0.0;
    assert_eq!(Controller::new(&cfg).unwrap_err(), ConfigError::Td);
}

#[test]
fn non_finite_measurement_gives_zero_and_a_flag() {
    for kind in ControllerKind::ALL {
        let cfg = ControllerConfig::preset(Preset::Paper, kind);
        let mut c = Controller::new(&cfg).unwrap();
        c.step(&sample(0.0), 0.05);
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let out = c.step(&sample(bad), 0.05);
            assert_eq!(out.v_cmd_mps, 0.0, "{kind:?}");
            assert!(out.flags.has(Flags::NON_FINITE_INPUT));
            assert!(out.flags.is_error());
            let out = c.step(&sample(0.0), bad);
            assert_eq!(out.v_cmd_mps, 0.0);
            assert!(out.flags.has(Flags::NON_FINITE_INPUT));
        }
        // A finite sample afterwards is served normally.
        let out = c.step(&sample(0.0), 0.05);
        assert!(!out.flags.is_error());
    }
}

#[test]
fn out_of_range_measurement_and_reference_are_flagged() {
    let cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::Pid);
    let mut c = Controller::new(&cfg).unwrap();
    let out = c.step(&sample(5.0), 0.05);
    assert!(out.flags.has(Flags::OUT_OF_RANGE));
    let out = c.step(&sample(0.0), 0.5);
    assert!(out.flags.has(Flags::REF_CLAMPED));
    assert!(!out.flags.is_error());
}

fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -0.2f32..0.2,
        2 => any::<f32>().prop_filter("finite", |v| v.is_finite()),
        1 => prop::sample::select(vec![f32::MAX, f32::MIN, 1e-45, -1e-45, 0.0, -0.0]),
    ]
}

fn any_input() -> impl Strategy<Value = (f32, f32, f32)> {
    prop_oneof![
        8 => (any_f32(), any_f32(), any_f32()),
        1 => (
            prop::sample::select(vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY]),
            any_f32(),
            any_f32()
        ),
        1 => (
            any_f32(),
            any_f32(),
            prop::sample::select(vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY])
        ),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// However absurd the input, the command is finite and within +-v_max;
    /// non-finite inputs give 0 with the error flag; nothing panics.
    #[test]
    fn command_is_always_finite_and_limited(
        kind in prop::sample::select(ControllerKind::ALL.to_vec()),
        preset in prop::sample::select(Preset::ALL.to_vec()),
        base_dt_s in prop::sample::select(vec![1e-4, 1e-3]),
        inputs in prop::collection::vec(any_input(), 1..40),
        hold_ticks in 1usize..400,
    ) {
        let mut cfg = ControllerConfig::preset(preset, kind);
        cfg.base_dt_s = base_dt_s;
        let v_max = cfg.limits.v_max_mps;
        let mut c = Controller::new(&cfg).unwrap();
        for (xo, xi, r) in inputs {
            let s = Sample { xo_m: xo, xi_m: xi, ..Sample::default() };
            for _ in 0..hold_ticks {
                let out = c.step(&s, r);
                prop_assert!(out.v_cmd_mps.is_finite());
                prop_assert!(out.v_cmd_mps.abs() <= v_max);
                if !(xo.is_finite() && r.is_finite()) {
                    prop_assert_eq!(out.v_cmd_mps, 0.0);
                    prop_assert!(out.flags.has(Flags::NON_FINITE_INPUT));
                } else {
                    prop_assert!(!out.flags.has(Flags::NON_FINITE_INPUT));
                }
                prop_assert!(!out.flags.has(Flags::NON_FINITE_OUTPUT));
                let u = c.position_command();
                prop_assert!((cfg.limits.x_min_m..=cfg.limits.x_max_m).contains(&u));
            }
        }
    }
}

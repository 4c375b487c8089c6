//! Supervisor and control loop (dca_app::supervisor).

use dca_app::settings::Settings;
use dca_app::supervisor::{ControlLoop, Faults, Reference, Refused, State, SupervisorLimits};
use dca_core::controller::{Controller, Sample};

fn lp() -> ControlLoop {
    let s = Settings::default();
    ControlLoop::new(s.validate().unwrap(), s.limits, 1e-3)
}

fn at(xo: f32) -> Sample {
    Sample {
        xo_m: xo,
        xi_m: xo,
        p1_pa: 6.4e5,
        p2_pa: 1.0e6,
        ft_n: 0.0,
    }
}

#[test]
fn idle_never_commands_and_arm_holds_the_measured_position() {
    let mut l = lp();
    for _ in 0..10 {
        let o = l.tick(&at(0.02), None);
        assert_eq!(o.v_cmd_mps, 0.0);
        assert_eq!(o.state, State::Idle as u8);
    }
    l.arm().unwrap();
    assert_eq!(l.reference_now(), 0.02);
    assert_eq!(l.arm(), Err(Refused::NotIdle));
    l.goto(0.05).unwrap();
    assert_eq!(l.supervisor().state(), State::Running);
    let mut moved = false;
    for _ in 0..300 {
        let o = l.tick(&at(0.02), None);
        moved |= o.v_cmd_mps > 0.0;
    }
    assert!(moved, "the controller drives towards the target");
    l.stop().unwrap();
    assert_eq!(l.supervisor().state(), State::Armed);
    assert_eq!(l.reference_now(), 0.05);
    l.disarm();
    assert_eq!(l.tick(&at(0.02), None).v_cmd_mps, 0.0);
    assert_eq!(l.goto(0.01), Err(Refused::NotArmed));
}

#[test]
fn each_sensor_fault_zeroes_the_command_on_the_same_tick_and_latches() {
    type Spoil = fn(&mut Sample);
    let cases: [(Spoil, u16); 6] = [
        (|s| s.xo_m = -0.009_985, Faults::SENSOR_RANGE), // open LVDT: rail code 0
        (|s| s.xo_m = f32::NAN, Faults::SENSOR_RANGE),
        (|s| s.ft_n = 1999.5, Faults::SENSOR_RANGE),
        (|s| s.p1_pa = 9.5e6, Faults::OVERPRESSURE),
        (|s| s.xi_m = 0.107, Faults::STROKE),
        (|s| s.xo_m = -0.006, Faults::STROKE),
    ];
    for (bad, bit) in cases {
        let mut l = lp();
        l.tick(&at(0.0), None);
        l.arm().unwrap();
        l.goto(0.08).unwrap();
        for _ in 0..150 {
            l.tick(&at(0.0), None);
        }
        assert_ne!(l.tick(&at(0.0), None).v_cmd_mps, 0.0);
        let mut s = at(0.0);
        bad(&mut s);
        let o = l.tick(&s, None);
        assert_eq!(o.v_cmd_mps, 0.0, "bit {bit:#x}");
        assert_eq!(o.state, State::Fault as u8);
        assert!(Faults(o.faults).has(bit), "bit {bit:#x} in {:#x}", o.faults);
        // Latched: a good sample does not release it, arming is refused.
        assert_eq!(l.tick(&at(0.0), None).v_cmd_mps, 0.0);
        assert_eq!(l.arm(), Err(Refused::Faulted));
        l.supervisor_mut().clear().unwrap();
        assert_eq!(l.supervisor().state(), State::Idle);
        assert_eq!(l.supervisor_mut().clear(), Err(Refused::NoFault));
        // A fault still present trips again on the next tick.
        assert_eq!(l.tick(&s, None).state, State::Fault as u8);
    }
}

#[test]
fn external_trips_and_non_finite_references_fault() {
    let mut l = lp();
    l.tick(&at(0.0), None);
    l.arm().unwrap();
    l.supervisor_mut().trip(Faults::OVERRUN);
    assert_eq!(l.tick(&at(0.0), None).v_cmd_mps, 0.0);
    assert!(l.supervisor().faults().has(Faults::OVERRUN));
    l.supervisor_mut().clear().unwrap();
    l.arm().unwrap();
    let o = l.tick(&at(0.0), Some(f32::NAN));
    assert_eq!(o.v_cmd_mps, 0.0);
    assert!(Faults(o.faults).has(Faults::NON_FINITE));
}

#[test]
fn hil_frames_run_the_same_controller_as_a_bare_one() {
    // The loop, armed and fed frame references, commands exactly what a fresh
    // controller does: no supervisor arithmetic touches the command.
    let s = Settings::default();
    let mut bare = Controller::new(&s.controller).unwrap();
    let mut l = lp();
    l.tick(&at(0.0), None);
    l.arm().unwrap();
    for k in 0..2000u32 {
        let x = 0.04 * (k as f32 / 2000.0);
        let r = 0.05;
        let a = bare.step(&at(x), r);
        let b = l.tick(&at(x), Some(r));
        assert_eq!(a.v_cmd_mps.to_bits(), b.v_cmd_mps.to_bits(), "tick {k}");
        assert_eq!(b.state, State::Running as u8);
    }
}

#[test]
fn sine_reference_starts_at_rest_and_peaks_at_twice_the_amplitude() {
    let r = Reference::Sine {
        x0_m: 0.01,
        amplitude_m: 0.02,
        freq_hz: 0.25,
        k0: 1000,
    };
    assert_eq!(r.value(1000, 1e-3), 0.01);
    assert!((r.value(3000, 1e-3) - 0.05).abs() < 1e-6);
    assert!((r.value(5000, 1e-3) - 0.01).abs() < 1e-6);
    // Long runs keep the phase: 10^7 periods later it is still at rest.
    assert!((r.value(1000 + 4_000 * 10_000_000, 1e-3) - 0.01).abs() < 1e-6);
}

#[test]
fn limits_check_is_inclusive_and_rejects_nan_everywhere() {
    let l = SupervisorLimits::DEFAULT;
    assert_eq!(l.check(&at(0.0)), 0);
    let mut s = at(0.0);
    s.p2_pa = f32::NAN;
    assert_eq!(l.check(&s), Faults::SENSOR_RANGE);
    let mut s = at(0.0);
    s.xi_m = f32::INFINITY;
    assert_eq!(l.check(&s), Faults::SENSOR_RANGE);
}

#[test]
fn cosine_of_turns_matches_libm() {
    let mut worst = 0.0f64;
    for i in 0..=10_000 {
        let x = i as f32 / 10_000.0;
        let x = if x >= 1.0 { 0.0 } else { x };
        let want = (2.0 * std::f64::consts::PI * x as f64).cos();
        worst = worst.max((dca_app::supervisor::cos_turns(x) as f64 - want).abs());
    }
    assert!(worst < 1e-6, "worst error {worst}");
}

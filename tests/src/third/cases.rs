//! The cases of the third family: what each rig has, and the verdict a correct
//! diagnosis gives. Magnitudes were chosen from physics (what a real rig of this
//! size plausibly has) before any diagnosis was run, and were not changed after.

use super::effects::*;
use super::plant::{Rig, RigParams};

/// What kind of truth a case carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// One effect of docs/model.md section 12 (or `parameters`).
    Single,
    /// The nominal rig: expected `none`.
    Clean,
    /// A defect outside the vocabulary: expected `unexplained`.
    Outside,
    /// Two effects; either identifier is a right verdict.
    Pair,
}

/// One case.
#[derive(Clone, Debug)]
pub struct Case {
    /// Directory-safe name.
    pub name: &'static str,
    /// Kind of truth.
    pub kind: Kind,
    /// The right verdicts (two for a pair).
    pub truth: Vec<&'static str>,
    /// The rig.
    pub rig: Rig,
    /// One line: form and magnitude in words.
    pub what: &'static str,
}

fn with(f: impl FnOnce(&mut Effects)) -> Rig {
    let mut r = Rig::nominal();
    f(&mut r.effects);
    r
}

fn params(f: impl FnOnce(&mut RigParams)) -> Rig {
    let mut r = Rig::nominal();
    f(&mut r.params);
    r
}

const LEAK_A: Leakage = Leakage {
    g_m3pspa: 2.0e-14,
    widen_pa: 2.0e6,
};
const LEAK_B: Leakage = Leakage {
    g_m3pspa: 6.0e-14,
    widen_pa: 2.0e6,
};
const FRICTION_A: Friction = Friction {
    coulomb_n: 15.0,
    per_pa_n: 8.0e-6,
    static_ratio: 1.5,
    stribeck_mps: 2.0e-3,
    sigma0_npm: 2.0e6,
    sigma1_nspm: 2.0e3,
};
const FRICTION_B: Friction = Friction {
    coulomb_n: 40.0,
    per_pa_n: 1.5e-5,
    static_ratio: 1.3,
    stribeck_mps: 5.0e-3,
    sigma0_npm: 2.0e6,
    sigma1_nspm: 2.0e3,
};
const BACKLASH_A: Backlash = Backlash {
    play_m: 100e-6,
    stiffness_npm: 3.0e7,
    damping_nspm: 2.0e3,
    piston_kg: 1.0,
    seal_n: 20.0,
    seal_nspm: 500.0,
};
const BACKLASH_B: Backlash = Backlash {
    play_m: 300e-6,
    stiffness_npm: 1.5e7,
    damping_nspm: 1.5e3,
    piston_kg: 1.0,
    seal_n: 20.0,
    seal_nspm: 500.0,
};
const THERMAL_B: AccumulatorThermal = AccumulatorThermal {
    tau_s: 6.0,
    gamma: 1.4,
};
const LVDT_FILTER: SensorLag = SensorLag {
    lvdt_corner_hz: 40.0,
    lvdt_delay_s: 0.0,
};
const PI_THRESHOLDS_PA: [f64; 4] = [30e3, 100e3, 250e3, 500e3];

/// Every case of the family, in a fixed order.
pub fn all() -> Vec<Case> {
    use Kind::*;
    let c = |name, kind, truth: &[&'static str], rig, what| Case {
        name,
        kind,
        truth: truth.to_vec(),
        rig,
        what,
    };
    vec![
        c("leakage-a", Single, &["leakage"], with(|e| e.leakage = Some(LEAK_A)),
          "actuating-piston seal gap widening with dP: Q = G (1 + |dP|/2 MPa) dP, G = 2e-14 m^3/(s Pa)"),
        c("leakage-b", Single, &["leakage"], with(|e| e.leakage = Some(LEAK_B)),
          "as leakage-a, G = 6e-14 m^3/(s Pa) (about 0.6 mm/s of Xo creep at 600 N)"),
        c("friction-a", Single, &["friction"], with(|e| e.friction = Some(FRICTION_A)),
          "LuGre seal friction, Fc = 15 N + 8e-6 N/Pa (P1 + P2), Fs = 1.5 Fc, vs = 2 mm/s, sigma0 = 2e6 N/m"),
        c("friction-b", Single, &["friction"], with(|e| e.friction = Some(FRICTION_B)),
          "LuGre seal friction, Fc = 40 N + 1.5e-5 N/Pa (P1 + P2), Fs = 1.3 Fc, vs = 5 mm/s"),
        c("backlash-a", Single, &["backlash"], with(|e| e.backlash = Some(BACKLASH_A)),
          "0.1 mm coupling play, power piston of 1 kg with 20 N seal friction, contact 3e7 N/m"),
        c("backlash-b", Single, &["backlash"], with(|e| e.backlash = Some(BACKLASH_B)),
          "0.3 mm coupling play, contact 1.5e7 N/m"),
        c("air-a", Single, &["air"], with(|e| e.air = Some(Air { fraction: 0.004, dissolve_pa: 3.0e6 })),
          "0.4 % free air at atmosphere, isothermal bubbles dissolving with P (scale 3 MPa), both lines"),
        c("air-b", Single, &["air"], with(|e| e.air = Some(Air { fraction: 0.012, dissolve_pa: 3.0e6 })),
          "1.2 % free air, as air-a"),
        c("sensor_delay-a", Single, &["sensor_delay"], with(|e| e.lag = Some(LVDT_FILTER)),
          "LVDT conditioner: 2nd-order Butterworth at 40 Hz (about 5.6 ms group delay)"),
        c("sensor_delay-b", Single, &["sensor_delay"],
          with(|e| e.lag = Some(SensorLag { lvdt_corner_hz: 0.0, lvdt_delay_s: 5.0e-3 })),
          "LVDT acquisition transport delay of 5 ms"),
        c("motor_limit-a", Single, &["motor_limit"],
          with(|e| e.motor = Some(MotorLimit { peak_n: 1300.0, mass_eq_kg: 150.0, corner_mps: 0.06, no_load_mps: 0.10 })),
          "undersized servo with a heavy screw: 1300 N peak screw force, 150 kg reflected inertia, force falling from 60 to 100 mm/s"),
        c("motor_limit-b", Single, &["motor_limit"],
          with(|e| e.motor = Some(MotorLimit { peak_n: 1250.0, mass_eq_kg: 60.0, corner_mps: 0.03, no_load_mps: 0.08 })),
          "small servo on a low supply: 1250 N peak, 60 kg, force falling from 30 mm/s to zero at 80 mm/s"),
        c("hose_hysteresis-a", Single, &["hose_hysteresis"],
          with(|e| e.hysteresis = Some(HoseHysteresis { thresholds_pa: PI_THRESHOLDS_PA, weights_m3pp: [0.2e-13; 4] })),
          "Prandtl-Ishlinskii wall hysteresis, plays 30/100/250/500 kPa, 0.2e-13 m^3/Pa each, both hoses"),
        c("hose_hysteresis-b", Single, &["hose_hysteresis"],
          with(|e| e.hysteresis = Some(HoseHysteresis { thresholds_pa: PI_THRESHOLDS_PA, weights_m3pp: [0.5e-13; 4] })),
          "as hose_hysteresis-a, 0.5e-13 m^3/Pa each"),
        c("accumulator_thermal-a", Single, &["accumulator_thermal"],
          with(|e| e.thermal = Some(AccumulatorThermal { tau_s: 1.0, gamma: 1.4 })),
          "gas energy balance with shell heat exchange, tau = 1 s, gamma = 1.4"),
        c("accumulator_thermal-b", Single, &["accumulator_thermal"], with(|e| e.thermal = Some(THERMAL_B)),
          "as accumulator_thermal-a, tau = 6 s"),
        c("sensor_calibration-a", Single, &["sensor_calibration"],
          with(|e| e.calibration = Some(Calibration { channel: Channel::Lvdt, gain: 1.025, offset: 1.0e-4, quad: 0.0 })),
          "LVDT span +2.5 % and zero +0.1 mm"),
        c("sensor_calibration-b", Single, &["sensor_calibration"],
          with(|e| e.calibration = Some(Calibration { channel: Channel::P1, gain: 0.95, offset: 25.0e3, quad: 0.0 })),
          "line-1 pressure sensor span -5 % and zero +25 kPa"),
        c("parameters-bulk", Single, &["parameters"], params(|p| p.beta_e_pa = 0.7e9),
          "oil bulk modulus 0.7 GPa instead of 1.2 GPa, uniform (no pressure dependence)"),
        c("parameters-acc-servo", Single, &["parameters"],
          params(|p| {
              p.v_gas0_m3 = 0.07e-3;
              p.tau_m_s = 0.014;
          }),
          "accumulator gas volume 0.07 L instead of 0.1 L, servo time constant 14 ms instead of 10 ms"),
        c("parameters-mass-visc", Single, &["parameters"],
          params(|p| {
              p.m_kg = 70.0;
              p.c_visc_nspm = 300.0;
          }),
          "moving mass 70 kg instead of 50 kg, viscous damping 300 N s/m instead of 200"),
        c("clean-1", Clean, &["none"], Rig::nominal(), "nominal rig"),
        c("clean-2", Clean, &["none"], Rig::nominal(), "nominal rig, other noise seeds"),
        c("outside-orifice", Outside, &["unexplained"],
          with(|e| e.restriction = Some(Restriction { cd_area_m2: 1.0e-6, rho_kgpm3: 870.0, transition_pa: 20.0e3 })),
          "half-closed needle valve at the power cylinder's line-1 port, Cd A = 1e-6 m^2 (0.6 MPa at 0.1 m/s); the line-1 sensor sits at that port"),
        c("outside-ripple", Outside, &["unexplained"],
          with(|e| e.ripple = Some(DriveRipple { amplitude_mps: 4.0e-3, freq_hz: 50.0 })),
          "50 Hz mains pickup on the drive's speed reference, 4 mm/s amplitude"),
        c("outside-dropout", Outside, &["unexplained"],
          with(|e| e.dropout = Some(Dropout { rate_hz: 1.5, min_s: 0.02, max_s: 0.06 })),
          "loose LVDT connector: the reading freezes for 20-60 ms, 1.5 times a second on average"),
        c("pair-leak-backlash", Pair, &["leakage", "backlash"],
          with(|e| {
              e.leakage = Some(LEAK_A);
              e.backlash = Some(BACKLASH_A);
          }),
          "leakage-a and backlash-a"),
        c("pair-thermal-filter", Pair, &["accumulator_thermal", "sensor_delay"],
          with(|e| {
              e.thermal = Some(THERMAL_B);
              e.lag = Some(LVDT_FILTER);
          }),
          "accumulator_thermal-b and sensor_delay-a"),
    ]
}

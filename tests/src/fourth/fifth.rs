//! The fifth family of rigs: the fourth family's plant, sensors, scenarios
//! and controllers with the fifth family's effect forms (the variants of
//! [`Effect`] from [`Effect::MotorRipple`] on), written independently of
//! the gap diagnosis. Three or two forms each for `motor_limit`,
//! `hose_hysteresis`, `backlash` and `air`, one or two for the other
//! identifiers, three defects outside the vocabulary, two pairs and two
//! clean rigs. The truth stays here; the logs go to directories with
//! neutral names.

use super::cases::{numbered, Case, Kind, Row};
use super::effects::Effect;
use super::scenario::Scenario;

// ---------------------------------------------------------------------------
// The forms at magnitude `s` (1 = the single cases' magnitude).

/// motor_limit: speed-dependent commutation torque ripple.
pub fn motor_ripple() -> Effect {
    Effect::MotorRipple {
        m_eq: 35.0,
        k_v: 0.4,
        v_ref: 0.02,
        // 5.08 mm lead, 2 pole pairs: 12 commutations per turn.
        pitch: 0.00508 / 12.0,
    }
}

/// motor_limit: dead band and quantisation of the analog speed input.
pub fn motor_deadband(s: f64) -> Effect {
    Effect::MotorDeadband {
        v_db: 1.2e-3 * s,
        q: 0.2e-3,
    }
}

/// motor_limit: back-EMF torque-speed line from a low bus voltage, inductance,
/// current limit.
pub fn motor_backemf() -> Effect {
    Effect::MotorBackEmf {
        m_eq: 35.0,
        f_stall: 1200.0,
        v_noload: 0.075,
        tau_e: 1.5e-3,
        w_c: 2000.0,
        f_max: 900.0,
    }
}

/// hose_hysteresis: power-law creep spectrum and pressure-locked braid.
pub fn hose_creep_braid(s: f64) -> Effect {
    Effect::HoseCreepBraid {
        c_creep: 3.0e-13 * s,
        alpha: 0.3,
        c_braid: 1.5e-13 * s,
        r0: 5.0e4,
        mu: 0.15,
    }
}

/// hose_hysteresis: Preisach relays at fixed pressures.
pub fn hose_preisach(s: f64) -> Effect {
    Effect::HosePreisach {
        v_tot: 2.5e-7 * s,
        p_lo: 0.4e6,
        p_hi: 2.4e6,
        h_mean: 0.25e6,
        delta: 0.15e6,
    }
}

/// backlash: preloaded double nut worn into play in mid-stroke.
pub fn backlash_worn_nut(s: f64) -> Effect {
    Effect::BacklashWornNut {
        k_half: 3.0e7,
        g_pre: 8.0e-6,
        g_wear: 120.0e-6 * s,
        x_wear: 0.020,
        w_wear: 0.012,
        c_contact: 1500.0,
        m_piston: 1.5,
        c_piston: 300.0,
    }
}

/// backlash: nut flange shifting in its seat once the force overcomes the
/// bolts' clamping friction.
pub fn backlash_locked_play(half_play: f64, f_lock: f64) -> Effect {
    Effect::BacklashLockedPlay {
        half_play,
        f_lock,
        k_joint: 5.0e7,
        k_end: 3.0e7,
        c_joint: 1500.0,
        m_piston: 1.5,
        c_piston: 300.0,
    }
}

/// air: a bubble with heat exchange in the actuating cylinder's bore.
pub fn air_bubble(s: f64) -> Effect {
    Effect::AirBubbleThermal {
        v_ref: 0.35e-6 * s,
        p_ref_abs: 7.4e5,
        tau_th: 0.15,
    }
}

/// air: a slug behind hose 1's oil column.
pub fn air_slug() -> Effect {
    Effect::AirSlug {
        v_slug: 0.3e-6,
        p_ref_abs: 7.4e5,
        kappa: 1.3,
        // rho l / (pi a^2): 870 kg/m^3, 1 m, 3 mm.
        inertance: 3.08e7,
        resistance: 3.0e9,
    }
}

/// leakage: score in the actuating bore between 18 and 34 mm.
pub fn leak_scored(s: f64) -> Effect {
    Effect::LeakScoredBore {
        g_max: 8.0e-14 * s,
        x_a: 0.018,
        x_b: 0.034,
        edge: 0.002,
    }
}

/// friction: side-load friction of an eccentric load on a bent rod.
pub fn friction_side_load() -> Effect {
    Effect::FrictionSideLoad {
        mu: 0.18,
        n0: 180.0,
        ecc: 0.006,
        span0: 0.14,
        v_s: 5.0e-4,
    }
}

/// sensor_delay: the LVDT through an asynchronous sample-and-hold module.
pub fn lvdt_sample_hold(period: f64, transport: f64) -> Effect {
    Effect::LvdtSampleHold {
        period,
        phase: 0.7e-3,
        transport,
    }
}

/// accumulator_thermal: convection driven by the gas's motion (`s` scales
/// the heat transfer).
pub fn acc_forced(s: f64) -> Effect {
    Effect::AccumulatorForcedConvection {
        tau_still: 6.0 / s,
        q_ref: 3.0e-6,
    }
}

/// sensor_calibration: the encoder's lead is not the screw's.
pub fn cal_lead() -> Effect {
    Effect::ScrewLeadError {
        lead_err: 0.016,
        wobble: 5.0e-6,
        lead: 0.00508,
    }
}

/// sensor_calibration: the load cell's gain, zero and cubic.
pub fn cal_load_cell() -> Effect {
    Effect::LoadCellError {
        gain_err: -0.06,
        offset: 15.0,
        cubic: -20.0,
        f_ref: 1000.0,
    }
}

/// Every case of the fifth family, in report order (mixed, so that the
/// neutral numbers do not group the identifiers).
pub fn all() -> Vec<Case> {
    numbered(rows(), 0x5_F1F1_0000)
}

fn rows() -> Vec<Row> {
    use Kind::*;
    use Scenario::*;
    vec![
        (
            "motor-ripple",
            Single,
            vec!["motor_limit"],
            vec![motor_ripple()],
            "ripple +-20 % of the force at speed (+-10 % at 20 mm/s), every 0.42 mm",
            (Heavy, 1),
            (Ramps, 5),
        ),
        (
            "hose-preisach",
            Single,
            vec!["hose_hysteresis"],
            vec![hose_preisach(1.0)],
            "18 relays per hose, 0.25 cm^3 in all, centres 0.4-2.4 MPa",
            (Reversals, 2),
            (Stairs, 7),
        ),
        (
            "clean-1",
            Clean,
            vec![],
            vec![],
            "nominal",
            (Chirp, 6),
            (LoadSteps, 2),
        ),
        (
            "backlash-worn-nut",
            Single,
            vec!["backlash"],
            vec![backlash_worn_nut(1.0)],
            "preload 8 um (120 N), worn 120 um at Xi 20 +- 12 mm (112 um play)",
            (Reversals, 1),
            (Stairs, 5),
        ),
        (
            "air-slug",
            Single,
            vec!["air"],
            vec![air_slug()],
            "0.3 cm^3 slug (kappa 1.3) behind hose 1's oil column (~50 Hz)",
            (Square, 7),
            (Chirp, 2),
        ),
        (
            "lvdt-core",
            Outside,
            vec![],
            vec![Effect::StickyLvdtCore { half_play: 40e-6 }],
            "LVDT core play +-40 um",
            (Reversals, 4),
            (Stairs, 6),
        ),
        (
            "motor-deadband",
            Single,
            vec!["motor_limit"],
            vec![motor_deadband(1.0)],
            "dead band 1.2 mm/s, steps of 0.2 mm/s",
            (Reversals, 3),
            (Chirp, 6),
        ),
        (
            "leak-scored",
            Single,
            vec!["leakage"],
            vec![leak_scored(1.0)],
            "8e-14 m^3/(s Pa) over Xo 18-34 mm (1.6e-7 m^3/s at 2 MPa)",
            (Stairs, 1),
            (Ramps, 4),
        ),
        (
            "hose-creep-braid",
            Single,
            vec!["hose_hysteresis"],
            vec![hose_creep_braid(1.0)],
            "creep 3e-13 m^3/Pa (alpha 0.3), braid 1.5e-13 m^3/Pa, yield 50 kPa + 0.15 P",
            (Square, 1),
            (Reversals, 4),
        ),
        (
            "backlash-locked-play",
            Single,
            vec!["backlash"],
            vec![backlash_locked_play(70e-6, 300.0)],
            "play +-70 um, clamping friction 300 N",
            (LoadSteps, 2),
            (Square, 3),
        ),
        (
            "air-bubble",
            Single,
            vec!["air"],
            vec![air_bubble(1.0)],
            "0.35 cm^3 bubble at 0.74 MPa abs, thermal 0.15 s",
            (Chirp, 4),
            (LowLoad, 1),
        ),
        (
            "params-mechanical",
            Single,
            vec!["parameters"],
            vec![Effect::ParamScale {
                m: 1.2,
                beta_e: 0.75,
                hose_c: 1.0,
                tau_m: 1.0,
                v_gas0: 1.25,
                c_visc: 1.3,
            }],
            "mass +20 %, bulk modulus -25 %, gas volume +25 %, viscous +30 %",
            (Square, 4),
            (Heavy, 1),
        ),
        (
            "motor-backemf",
            Single,
            vec!["motor_limit"],
            vec![motor_backemf()],
            "low bus: stall 1200 N, no-load 75 mm/s, L/R 1.5 ms, limit 900 N",
            (Stairs, 4),
            (Square, 6),
        ),
        (
            "friction-side-load",
            Single,
            vec!["friction"],
            vec![friction_side_load()],
            "mu 0.18, bent rod 180 N, load 6 mm off axis, span 140 mm - Xo",
            (Reversals, 6),
            (Heavy, 3),
        ),
        (
            "pair-nut-convection",
            Pair,
            vec!["backlash", "accumulator_thermal"],
            vec![backlash_worn_nut(1.0), acc_forced(0.25)],
            "backlash (worn nut) 1x + accumulator_thermal (forced convection) 0.25x",
            (Ramps, 5),
            (Reversals, 2),
        ),
        (
            "mains-hum",
            Outside,
            vec![],
            vec![Effect::MainsHum {
                amp: 20e3,
                freq_hz: 49.95,
                amp3: 6e3,
                phase: 0.4,
            }],
            "P1 + 20 kPa at 49.95 Hz + 6 kPa third harmonic",
            (LoadSteps, 5),
            (Chirp, 7),
        ),
        (
            "delay-sample-hold",
            Single,
            vec!["sensor_delay"],
            vec![lvdt_sample_hold(4.1e-3, 1.2e-3)],
            "LVDT sampled every 4.1 ms (asynchronous), + 1.2 ms, held (~3.3 ms mean)",
            (Chirp, 5),
            (Square, 1),
        ),
        (
            "hose-preisach-weak",
            Weak,
            vec!["hose_hysteresis"],
            vec![hose_preisach(0.4)],
            "Preisach wall at 0.4x (0.1 cm^3)",
            (Square, 6),
            (Reversals, 3),
        ),
        (
            "acc-forced",
            Single,
            vec!["accumulator_thermal"],
            vec![acc_forced(1.0)],
            "still gas 6 s, transfer doubling at 3 cm^3/s of gas flow",
            (Heavy, 2),
            (Stairs, 4),
        ),
        (
            "cal-lead",
            Single,
            vec!["sensor_calibration"],
            vec![cal_lead()],
            "lead 5.08 mm read as 5 mm (+1.6 %), 5 um per-turn wobble",
            (Stairs, 3),
            (Chirp, 5),
        ),
        (
            "backlash-locked-play-weak",
            Weak,
            vec!["backlash"],
            vec![backlash_locked_play(30e-6, 250.0)],
            "play +-30 um, clamping friction 250 N",
            (LoadSteps, 1),
            (Reversals, 7),
        ),
        (
            "load-fixture",
            Outside,
            vec![],
            vec![Effect::LoadFixture {
                m_f: 8.0,
                k_f: 1.5e5,
                c_f: 250.0,
            }],
            "8 kg fixture on a 1.5e5 N/m clevis (22 Hz)",
            (Square, 1),
            (Heavy, 4),
        ),
        (
            "air-bubble-weak",
            Weak,
            vec!["air"],
            vec![air_bubble(0.35)],
            "bubble at 0.35x (0.12 cm^3)",
            (LowLoad, 2),
            (Chirp, 6),
        ),
        (
            "cal-load-cell",
            Single,
            vec!["sensor_calibration"],
            vec![cal_load_cell()],
            "load cell gain -6 %, zero +15 N, cubic -20 N at 1 kN",
            (Ramps, 1),
            (LoadSteps, 7),
        ),
        (
            "pair-braid-hold",
            Pair,
            vec!["hose_hysteresis", "sensor_delay"],
            vec![hose_creep_braid(1.0), lvdt_sample_hold(2.0e-3, 0.5e-3)],
            "hose_hysteresis (creep + braid) 1x + sensor_delay (2 ms sampling, 0.5 ms)",
            (Stairs, 2),
            (Square, 6),
        ),
        (
            "motor-deadband-weak",
            Weak,
            vec!["motor_limit"],
            vec![motor_deadband(0.5)],
            "dead band 0.6 mm/s, steps of 0.2 mm/s",
            (Chirp, 3),
            (Reversals, 5),
        ),
        (
            "params-hydraulic",
            Single,
            vec!["parameters"],
            vec![
                Effect::ParamScale {
                    m: 1.0,
                    beta_e: 1.0,
                    hose_c: 0.8,
                    tau_m: 1.3,
                    v_gas0: 1.0,
                    c_visc: 1.0,
                },
                Effect::ParamScaleHydraulic {
                    p_acc0: 0.8,
                    g_acc: 0.7,
                    aa: 1.0,
                    l: 1.0,
                },
            ],
            "hose compliance -20 %, servo tau +30 %, precharge -20 %, restrictor -30 %",
            (Chirp, 1),
            (Ramps, 2),
        ),
        (
            "clean-2",
            Clean,
            vec![],
            vec![],
            "nominal",
            (Heavy, 7),
            (Reversals, 1),
        ),
    ]
}

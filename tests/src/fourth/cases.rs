//! The case list of the fourth family: the truth of every rig stays here
//! (the diagnosis only sees the CSV files, in directories with neutral names).

use dca_core::{ControllerKind, Preset};

use super::effects::Effect;
use super::plant::ix;
use super::rig::Rig;
use super::scenario::{col, run, Ctl, RunSpec, Scenario};

/// What a case is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// One effect at a clearly visible magnitude.
    Single,
    /// One effect, weaker.
    Weak,
    /// Two effects of different identifiers.
    Pair,
    /// The nominal plant (expected `none`).
    Clean,
    /// A defect outside the vocabulary (expected `unexplained`).
    Outside,
}

impl Kind {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Single => "single",
            Self::Weak => "weak",
            Self::Pair => "pair",
            Self::Clean => "clean",
            Self::Outside => "outside",
        }
    }
}

/// One rig with its fit and check runs.
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    /// Neutral directory name (`rig-07`): reveals nothing of the truth.
    pub id: String,
    /// Descriptive label (kept out of the logs).
    pub label: &'static str,
    /// Kind.
    pub kind: Kind,
    /// Identifiers of plant.md section 12, one per effect of a single, weak
    /// or pair case (in the order of `effects`); empty for clean and
    /// outside cases.
    pub truth: Vec<&'static str>,
    /// The rig's effects.
    pub effects: Vec<Effect>,
    /// One line on the magnitude.
    pub magnitude: &'static str,
    /// The fit run.
    pub fit: RunSpec,
    /// The held-out check run.
    pub check: RunSpec,
}

impl Case {
    /// The expected verdict: the identifier, `none`, `unexplained`, or for a
    /// pair both identifiers joined by `+`.
    pub fn expected(&self) -> String {
        match self.kind {
            Kind::Clean => "none".into(),
            Kind::Outside => "unexplained".into(),
            _ => self.truth.join("+"),
        }
    }

    /// True when `verdict` is right for this case (for a pair: either
    /// member).
    pub fn is_right(&self, verdict: &str) -> bool {
        match self.kind {
            Kind::Clean => verdict == "none",
            Kind::Outside => verdict == "unexplained",
            _ => self.truth.contains(&verdict),
        }
    }

    /// The rig.
    pub fn rig(&self) -> Rig {
        Rig::new(&self.effects)
    }

    /// How far the rig moves in 0.2 s from its rest state with no command
    /// and no load: |dXo|, |dXi| (m), |dP1|, |dP2| (Pa); `None` where a
    /// state turns non-finite.
    pub fn drift_at_rest(&self) -> Option<[f64; 4]> {
        let rig = self.rig();
        let x0 = rig.rest(0.0);
        let mut x = x0;
        for k in 0..2000 {
            x = rig.step(k as f64 * 1e-4, &x, 0.0, 0.0);
        }
        x.iter()
            .all(|v| v.is_finite())
            .then(|| [ix::XO, ix::XI, ix::P1, ix::P2].map(|i| (x[i] - x0[i]).abs()))
    }
}

// ---------------------------------------------------------------------------
// The effect forms at magnitude `s` (1 = the single cases' magnitude).

/// leakage A: orifice seal across the actuating piston.
pub fn leak_orifice(s: f64) -> Effect {
    Effect::LeakOrifice {
        k: 6.0e-11 * s,
        v_open: 0.02,
        p_lam: 2.0e4,
    }
}

/// leakage B: laminar gap across the power piston, dilating with dP.
pub fn leak_gap(s: f64) -> Effect {
    Effect::LeakDilatingGap {
        g0: 5.0e-15 * s,
        p_dil: 1.5e6,
    }
}

/// friction A: LuGre with pressure-dependent levels.
pub fn friction_lugre(s: f64) -> Effect {
    Effect::FrictionLuGre {
        fc0: 30.0 * s,
        kp: 1.5e-5 * s,
        ratio_s: 1.6,
        vs: 0.003,
        sigma0: 1.0e6,
        sigma1: 2000.0,
    }
}

/// friction B: Karnopp stick-slip, asymmetric Coulomb.
pub fn friction_karnopp(s: f64) -> Effect {
    Effect::FrictionKarnopp {
        f_stat: 110.0 * s,
        fc_ext: 75.0 * s,
        fc_ret: 50.0 * s,
        v_eps: 2.0e-4,
        c_stick: 25_000.0,
    }
}

/// backlash A: nut play with the piston's own mass.
pub fn backlash_play(s: f64) -> Effect {
    Effect::BacklashPlay {
        half_play: 0.15e-3 * s,
        k_contact: 2.0e7,
        c_contact: 2000.0,
        m_piston: 1.0,
        c_piston: 300.0,
    }
}

/// backlash B: compliant coupling with Dahl hysteresis.
pub fn backlash_coupling(s: f64) -> Effect {
    Effect::BacklashHysteresisCoupling {
        k_lin: 1.2e6 / s,
        sigma: 2.0e7,
        f_dahl: 100.0 * s,
        c_coupling: 1500.0,
        m_piston: 1.0,
        c_piston: 300.0,
    }
}

/// air A: free air with dissolution kinetics in both lines.
pub fn air_dissolving(s: f64) -> Effect {
    Effect::AirDissolving {
        a_tot: 2.0e-6 * s,
        henry: 1.0e-12 * s,
        tau_release: 0.3,
        tau_dissolve: 3.0,
    }
}

/// air B: trapped adiabatic pocket in hose 1.
pub fn air_pocket(s: f64) -> Effect {
    Effect::AirPocket {
        vb_ref: 2.5e-7 * s,
        p_ref_abs: 7.4e5,
        kappa: 1.4,
    }
}

/// sensor_delay A: LVDT filter and transport delay.
pub fn lvdt_delay(f_c_hz: f64, delay_s: f64) -> Effect {
    Effect::LvdtFilterDelay { f_c_hz, delay_s }
}

/// sensor_delay B: pressure membranes.
pub fn membrane() -> Effect {
    Effect::PressureMembrane {
        f_n_hz: 6.0,
        zeta: 0.7,
    }
}

/// motor_limit A: current-limited PI speed loop with windup.
pub fn drive_current(f_max: f64) -> Effect {
    Effect::DriveCurrentLimit {
        m_eq: 80.0,
        f_max,
        kv: 8.0e4,
        ki: 4.0e7,
        c_screw: 2500.0,
    }
}

/// motor_limit B: ramp limiter and voltage speed ceiling.
pub fn drive_slew() -> Effect {
    Effect::DriveSlewVoltage {
        a_max: 1.5,
        f_stall: 1500.0,
    }
}

/// hose_hysteresis A: Bouc-Wen.
pub fn hose_boucwen() -> Effect {
    Effect::HoseBoucWen {
        c_h: 1.5e-13,
        p_z: 5.0e5,
        beta: 0.5,
        gamma: 0.5,
        n: 1.5,
    }
}

/// hose_hysteresis B: Prandtl-Ishlinskii stops.
pub fn hose_stops() -> Effect {
    Effect::HoseStops {
        r: [0.1e6, 0.2e6, 0.4e6, 0.7e6, 1.2e6],
        c: [0.5e-13, 0.4e-13, 0.3e-13, 0.25e-13, 0.2e-13],
    }
}

/// accumulator_thermal A: gas-wall-ambient.
pub fn acc_wall() -> Effect {
    Effect::AccumulatorWall {
        tau_gw: 0.7,
        wall_ratio: 4.0,
        tau_wa: 20.0,
    }
}

/// accumulator_thermal B: van der Waals gas, natural convection.
pub fn acc_convection() -> Effect {
    Effect::AccumulatorConvection {
        k_nc: 1.0,
        a_vdw: 0.137,
        b_vdw: 3.87e-5,
    }
}

/// sensor_calibration A: LVDT gain and cubic bend.
pub fn cal_lvdt() -> Effect {
    Effect::LvdtNonlinear {
        gain_err: 0.03,
        cubic: 0.4e-3,
        center: 0.05,
        half_span: 0.06,
    }
}

/// sensor_calibration B: P1 saturating transducer.
pub fn cal_p1() -> Effect {
    Effect::P1Saturating {
        p_sat: 5.0e6,
        offset: 25.0e3,
    }
}

fn ctl(kind: ControllerKind, preset: Preset) -> Ctl {
    Ctl { kind, preset }
}

/// MPC-ESO, paper preset.
const C1: Ctl = Ctl {
    kind: ControllerKind::MpcEso,
    preset: Preset::Paper,
};

/// The controllers used, by number (1-7).
pub fn controller(n: usize) -> Ctl {
    use ControllerKind as K;
    match n {
        1 => C1,
        2 => ctl(K::Mpc, Preset::Paper),
        3 => ctl(K::Pid, Preset::Paper),
        4 => ctl(K::FuzzyPid, Preset::Paper),
        5 => ctl(K::CmpcEso, Preset::Limit),
        6 => ctl(K::MpcEso, Preset::Fast),
        7 => ctl(K::Pid, Preset::Fast),
        _ => panic!("no controller {n}"),
    }
}

/// One case of the table: label, kind, the true identifiers, the effects,
/// the magnitude in words, and the fit and check runs (scenario and
/// controller number of [`controller`]).
pub type Row = (
    &'static str,
    Kind,
    Vec<&'static str>,
    Vec<Effect>,
    &'static str,
    (Scenario, usize),
    (Scenario, usize),
);

/// Every case of the family, in report order.
pub fn all() -> Vec<Case> {
    let rows = [
        singles_seals_and_mechanics(),
        singles_sensors_servo_hose_accumulator(),
        singles_calibration_and_parameters(),
        weaker_pairs_and_clean(),
        outside_the_vocabulary(),
    ];
    numbered(rows.into_iter().flatten(), 0x4_F0F0_0000)
}

/// The cases of `rows` with neutral names (`rig-01`, ...) in their order,
/// the fit run of case i seeded `seed0 + 2 i` and its check run the next.
pub fn numbered(rows: impl IntoIterator<Item = Row>, seed0: u64) -> Vec<Case> {
    rows.into_iter()
        .enumerate()
        .map(|(i, (label, kind, truth, effects, magnitude, f, c))| {
            let seed = seed0 + 2 * i as u64;
            Case {
                id: format!("rig-{:02}", i + 1),
                label,
                kind,
                truth,
                effects,
                magnitude,
                fit: RunSpec {
                    scenario: f.0,
                    ctl: controller(f.1),
                    seed,
                },
                check: RunSpec {
                    scenario: c.0,
                    ctl: controller(c.1),
                    seed: seed + 1,
                },
            }
        })
        .collect()
}

fn singles_seals_and_mechanics() -> Vec<Row> {
    use Kind::*;
    use Scenario::*;
    vec![
        (
            "leak-orifice",
            Single,
            vec!["leakage"],
            vec![leak_orifice(1.0)],
            "k 6e-11 m^3/(s Pa^0.5), doubling at 20 mm/s (~9e-8 m^3/s at 2.2 MPa)",
            (LoadSteps, 1),
            (Ramps, 3),
        ),
        (
            "leak-gap",
            Single,
            vec!["leakage"],
            vec![leak_gap(1.0)],
            "g0 5e-15 m^3/(s Pa), gap doubling at 1.5 MPa (~1.7e-7 m^3/s at 2.2 MPa)",
            (Ramps, 6),
            (Stairs, 2),
        ),
        (
            "friction-lugre",
            Single,
            vec!["friction"],
            vec![friction_lugre(1.0)],
            "Fc 30 N + 1.5e-5 N/Pa (P1+P2) (~55 N at rest), Fs 1.6 Fc, vs 3 mm/s",
            (Reversals, 1),
            (Stairs, 4),
        ),
        (
            "friction-karnopp",
            Single,
            vec!["friction"],
            vec![friction_karnopp(1.0)],
            "stiction 110 N, Coulomb 75 N out / 50 N in",
            (Stairs, 3),
            (Reversals, 6),
        ),
        (
            "backlash-play",
            Single,
            vec!["backlash"],
            vec![backlash_play(1.0)],
            "play 0.30 mm total, contact 2e7 N/m, piston 1 kg",
            (LoadSteps, 2),
            (Reversals, 1),
        ),
        (
            "backlash-coupling",
            Single,
            vec!["backlash"],
            vec![backlash_coupling(1.0)],
            "1.2e6 N/m coupling (0.6 mm at 700 N) with a 100 N Dahl loop",
            (Reversals, 7),
            (LoadSteps, 5),
        ),
        (
            "air-dissolving",
            Single,
            vec!["air"],
            vec![air_dissolving(1.0)],
            "2 cm^3 normal air per line, Henry 1e-12 m^3/Pa (0.17 cm^3 free at rest in line 1)",
            (LowLoad, 1),
            (Chirp, 3),
        ),
        (
            "air-pocket",
            Single,
            vec!["air"],
            vec![air_pocket(1.0)],
            "0.25 cm^3 adiabatic pocket in hose 1 at rest",
            (Chirp, 2),
            (LowLoad, 2),
        ),
    ]
}

/// Singles, two forms per identifier: sensor delays, servo, hose wall and accumulator.
fn singles_sensors_servo_hose_accumulator() -> Vec<Row> {
    use Kind::*;
    use Scenario::*;
    vec![
        (
            "delay-lvdt",
            Single,
            vec!["sensor_delay"],
            vec![lvdt_delay(40.0, 3.0e-3)],
            "LVDT 40 Hz Butterworth + 3 ms delay (~8.6 ms lag)",
            (Square, 6),
            (Chirp, 1),
        ),
        (
            "delay-membrane",
            Single,
            vec!["sensor_delay"],
            vec![membrane()],
            "P1, P2 through 6 Hz, zeta 0.7 membranes (~37 ms lag)",
            (LoadSteps, 1),
            (Square, 7),
        ),
        (
            "motor-current",
            Single,
            vec!["motor_limit"],
            vec![drive_current(520.0)],
            "current limit 520 N on an 80 kg reflected inertia, PI speed loop with windup",
            (Square, 6),
            (Heavy, 5),
        ),
        (
            "motor-slew",
            Single,
            vec!["motor_limit"],
            vec![drive_slew()],
            "acceleration 1.5 m/s^2, speed ceiling falling to 0 at 1500 N",
            (Square, 5),
            (Stairs, 4),
        ),
        (
            "hose-boucwen",
            Single,
            vec!["hose_hysteresis"],
            vec![hose_boucwen()],
            "Bouc-Wen 1.5e-13 m^3/Pa over 0.5 MPa per hose (loop 0.15 cm^3)",
            (Reversals, 2),
            (Square, 1),
        ),
        (
            "hose-stops",
            Single,
            vec!["hose_hysteresis"],
            vec![hose_stops()],
            "5 stops, 1.65e-13 m^3/Pa in all, yield 0.1-1.2 MPa",
            (Square, 3),
            (Reversals, 6),
        ),
        (
            "acc-wall",
            Single,
            vec!["accumulator_thermal"],
            vec![acc_wall()],
            "gas-wall 0.7 s, wall 4x gas capacity, wall-ambient 20 s",
            (Ramps, 1),
            (Stairs, 3),
        ),
        (
            "acc-convection",
            Single,
            vec!["accumulator_thermal"],
            vec![acc_convection()],
            "van der Waals N2, natural convection 1.0 W/K^(4/3)",
            (Stairs, 5),
            (Ramps, 4),
        ),
    ]
}

/// Singles, two forms per identifier: sensor calibration and parameters.
fn singles_calibration_and_parameters() -> Vec<Row> {
    use Kind::*;
    use Scenario::*;
    vec![
        (
            "cal-lvdt",
            Single,
            vec!["sensor_calibration"],
            vec![cal_lvdt()],
            "LVDT gain +3 %, cubic 0.4 mm at the ends of 50 +- 60 mm",
            (Chirp, 2),
            (Stairs, 1),
        ),
        (
            "cal-p1",
            Single,
            vec!["sensor_calibration"],
            vec![cal_p1()],
            "P1 = 5 MPa tanh(P1/5 MPa) + 25 kPa",
            (LoadSteps, 3),
            (Ramps, 6),
        ),
        (
            "params-hydraulic",
            Single,
            vec!["parameters"],
            vec![Effect::ParamScale {
                m: 1.0,
                beta_e: 0.7,
                hose_c: 1.35,
                tau_m: 1.0,
                v_gas0: 1.0,
                c_visc: 1.0,
            }],
            "bulk modulus -30 %, hose compliances +35 %",
            (Square, 1),
            (LoadSteps, 4),
        ),
        (
            "params-mechanical",
            Single,
            vec!["parameters"],
            vec![Effect::ParamScale {
                m: 1.35,
                beta_e: 1.0,
                hose_c: 1.0,
                tau_m: 1.4,
                v_gas0: 0.7,
                c_visc: 1.3,
            }],
            "mass +35 %, servo tau +40 %, gas volume -30 %, viscous +30 %",
            (Stairs, 6),
            (Chirp, 2),
        ),
    ]
}

/// Weaker versions of four singles, pairs, and clean rigs.
fn weaker_pairs_and_clean() -> Vec<Row> {
    use Kind::*;
    use Scenario::*;
    vec![
        // Weaker versions.
        (
            "leak-orifice-weak",
            Weak,
            vec!["leakage"],
            vec![leak_orifice(0.35)],
            "leakage A at 0.35x",
            (LoadSteps, 4),
            (Ramps, 1),
        ),
        (
            "friction-lugre-weak",
            Weak,
            vec!["friction"],
            vec![friction_lugre(0.4)],
            "friction A at 0.4x",
            (Reversals, 3),
            (Stairs, 6),
        ),
        (
            "air-pocket-weak",
            Weak,
            vec!["air"],
            vec![air_pocket(0.35)],
            "air B at 0.35x (0.09 cm^3)",
            (Chirp, 7),
            (Stairs, 2),
        ),
        (
            "delay-lvdt-weak",
            Weak,
            vec!["sensor_delay"],
            vec![lvdt_delay(120.0, 1.0e-3)],
            "LVDT 120 Hz + 1 ms (~2.9 ms lag)",
            (Square, 7),
            (Chirp, 6),
        ),
        // Pairs.
        (
            "pair-karnopp-gap",
            Pair,
            vec!["friction", "leakage"],
            vec![friction_karnopp(0.5), leak_gap(2.0)],
            "friction B 0.5x + leakage B 2x",
            (Stairs, 1),
            (LoadSteps, 3),
        ),
        (
            "pair-air-current",
            Pair,
            vec!["air", "motor_limit"],
            vec![air_dissolving(0.5), drive_current(520.0)],
            "air A 0.5x + motor_limit A 1x",
            (Square, 1),
            (Heavy, 5),
        ),
        (
            "pair-play-wall",
            Pair,
            vec!["backlash", "accumulator_thermal"],
            vec![backlash_play(0.5), acc_wall()],
            "backlash A 0.5x + accumulator_thermal A 1x",
            (Ramps, 2),
            (Reversals, 4),
        ),
        // Clean rigs.
        (
            "clean-1",
            Clean,
            vec![],
            vec![],
            "nominal",
            (Stairs, 1),
            (Chirp, 3),
        ),
        (
            "clean-2",
            Clean,
            vec![],
            vec![],
            "nominal",
            (Square, 5),
            (LoadSteps, 6),
        ),
    ]
}

/// Effects outside the vocabulary.
fn outside_the_vocabulary() -> Vec<Row> {
    use Kind::*;
    use Scenario::*;
    vec![
        // Outside the vocabulary.
        (
            "spring",
            Outside,
            vec![],
            vec![Effect::CentringSpring {
                k: 6000.0,
                x0: 0.020,
            }],
            "6 kN/m spring towards Xo = 20 mm",
            (Ramps, 1),
            (Square, 2),
        ),
        (
            "lvdt-drift",
            Outside,
            vec![],
            vec![Effect::LvdtDrift { rate: 70e-6 }],
            "LVDT offset +70 um/s (0.7 mm at 10 s)",
            (Stairs, 6),
            (Reversals, 2),
        ),
        (
            "relief",
            Outside,
            vec![],
            vec![Effect::ReliefToTank {
                p_crack: 2.0e6,
                g: 2.5e-13,
            }],
            "line 1 -> tank above 2.0 MPa, 2.5e-13 m^3/(s Pa)",
            (LoadSteps, 1),
            (Ramps, 3),
        ),
        (
            "rupture",
            Outside,
            vec![],
            vec![Effect::HoseRupture {
                t0: 2.0,
                g_rate: 4.0e-13,
            }],
            "line 2 -> tank, conductance growing 4e-13 m^3/(s Pa) per s from 2 s",
            (Chirp, 4),
            (Stairs, 5),
        ),
    ]
}

/// Noise-level reference of each logged channel for [`visibility`]: xi and
/// xo 13 um (the LVDT's noise with its quantisation; the encoder is weighed
/// like the LVDT), p1 and p2 5.2 kPa.
pub const SIGMA: [(usize, f64); 4] = [
    (col::XI, 13e-6),
    (col::XO, 13e-6),
    (col::P1, 5.2e3),
    (col::P2, 5.2e3),
];

/// How visible `effects` are in run `spec`: the rig with these effects and
/// the nominal rig, both with exact sensors and the same controller, the
/// channels' differences in units of [`SIGMA`], root mean square over the
/// run and the four channels.
pub fn visibility(effects: &[Effect], spec: &RunSpec) -> f64 {
    let nom = run(&Rig::nominal(), spec, false);
    let eff = run(&Rig::new(effects), spec, false);
    let mut acc = 0.0;
    for (c, s) in SIGMA {
        let ms: f64 = nom
            .rows
            .iter()
            .zip(&eff.rows)
            .map(|(a, b)| ((a[c] - b[c]) / s).powi(2))
            .sum::<f64>()
            / nom.rows.len() as f64;
        acc += ms;
    }
    (acc / SIGMA.len() as f64).sqrt()
}

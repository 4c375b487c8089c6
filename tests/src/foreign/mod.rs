//! An independent rig simulator for tests: the nominal plant of docs/model.md
//! written from the specification alone, realistic sensors, the dca-core
//! controller in the loop, and unmodelled effects whose mathematical forms
//! differ from the project's own effect models (see [`effects`]).
//!
//! Its logs (docs/interfaces.md section 1) are the input of robustness tests of
//! the gap diagnosis: the diagnosis never saw these forms.
//!
//! * [`cases`]: a small and a large magnitude per identifier of docs/model.md
//!   section 12, two clean cases, two pairs, and `motor_limit-speedcap` (a
//!   low no-load speed: the only motor limit that also shows in the `check`
//!   scenario, whose forces stay below any force limit that can hold the
//!   800 N of `fit`);
//! * [`log_csv`]: the run log of a case in a [`ForeignScenario`];
//! * [`simulate`]: the run with the noise-free signals too;
//! * [`magnitude`]: RMS difference to the clean run, per channel.

pub mod effects;
pub mod plant;
pub mod scenario;
pub mod sensors;

pub use effects::{Effect, Effects};
pub use scenario::{
    paper_scenario, rms_delta, simulate, simulate_substeps, ForeignRun, ForeignScenario, LogRow,
    Magnitude, ScenarioSpec,
};
pub use sensors::SensorMode;

use effects::{
    AirExp, BoucWenHose, ForceLimit, GasWallThermal, HertzPlay, LuGreFriction, OrificeLeakage,
    SensorLag,
};

/// A test case: effects in force and the truth the diagnosis should find.
#[derive(Clone, Debug, PartialEq)]
pub struct ForeignCase {
    /// Case name, e.g. `leakage-small`.
    pub name: String,
    /// The true identifiers (docs/model.md section 12); `["none"]` for a clean case.
    pub truth: Vec<&'static str>,
    /// The effects with their parameters.
    pub effects: Vec<Effect>,
    /// Mixed into the noise seed (0 for all but the second clean case, so
    /// that an effect run and the first clean run share their noise).
    pub noise_salt: u64,
}

impl ForeignCase {
    fn new(name: &str, effects: Vec<Effect>) -> Self {
        let truth = if effects.is_empty() {
            vec!["none"]
        } else {
            effects.iter().map(Effect::identifier).collect()
        };
        Self {
            name: name.to_string(),
            truth,
            effects,
            noise_salt: 0,
        }
    }

    /// The effects' forms and parameters, one per line.
    pub fn describe(&self) -> String {
        if self.effects.is_empty() {
            return "nominal plant".to_string();
        }
        self.effects
            .iter()
            .map(|e| format!("{}: {}", e.identifier(), e.describe()))
            .collect::<Vec<_>>()
            .join("\n")
    }
}

/// The first clean case (nominal plant, realistic sensors).
pub fn clean() -> ForeignCase {
    ForeignCase::new("clean-a", Vec::new())
}

fn leakage(k: f64) -> Effect {
    Effect::Leakage(OrificeLeakage { k, p_t: 20e3 })
}

fn friction(fc0: f64, k_p: f64, sigma0: f64, sigma1: f64) -> Effect {
    Effect::Friction(LuGreFriction {
        fc0,
        k_p,
        r_s: 1.5,
        v_s: 2e-3,
        sigma0,
        sigma1,
        v_d: 1e-3,
    })
}

fn backlash(play: f64, k_h: f64) -> Effect {
    Effect::Backlash(HertzPlay {
        play,
        k_h,
        hc_s: 5.0,
        m_piston: 0.3,
        c_seal: 100.0,
    })
}

fn air(a: f64, p_c: f64) -> Effect {
    Effect::Air(AirExp { a, p_c })
}

fn sensor_delay(lvdt_fn_hz: f64, p_delay_ticks: usize) -> Effect {
    Effect::SensorDelay(SensorLag {
        lvdt_fn_hz,
        lvdt_zeta: 0.7,
        p_delay_ticks,
    })
}

fn motor_limit(f_max: f64, v_nl: f64) -> Effect {
    Effect::MotorLimit(ForceLimit {
        m_eq: 150.0,
        f_max,
        v_nl,
    })
}

fn hose_hysteresis(phi: f64, z_max: f64) -> Effect {
    Effect::HoseHysteresis(BoucWenHose {
        phi,
        rho: 0.1,
        z_max,
        b: 0.5,
    })
}

fn accumulator_thermal(tau_gas_s: f64, wall_ratio: f64, tau_wall_s: f64) -> Effect {
    Effect::AccumulatorThermal(GasWallThermal {
        tau_gas_s,
        wall_ratio,
        tau_wall_s,
    })
}

/// All cases: two clean ones, a small and a large magnitude per identifier
/// (`<identifier>-small`, `<identifier>-large`), `motor_limit-speedcap` and
/// two pairs (`pair-...`).
pub fn cases() -> Vec<ForeignCase> {
    let mut clean_b = ForeignCase::new("clean-b", Vec::new());
    clean_b.noise_salt = 1;
    vec![
        clean(),
        clean_b,
        ForeignCase::new("leakage-small", vec![leakage(3e-11)]),
        ForeignCase::new("leakage-large", vec![leakage(2e-10)]),
        ForeignCase::new("friction-small", vec![friction(3.0, 0.5e-6, 3e5, 1e3)]),
        ForeignCase::new("friction-large", vec![friction(16.0, 4e-6, 1.5e6, 2e3)]),
        ForeignCase::new("backlash-small", vec![backlash(10e-6, 4e9)]),
        ForeignCase::new("backlash-large", vec![backlash(150e-6, 1.5e9)]),
        ForeignCase::new("air-small", vec![air(0.65, 1e6)]),
        ForeignCase::new("air-large", vec![air(0.95, 2e6)]),
        ForeignCase::new("sensor_delay-small", vec![sensor_delay(120.0, 10)]),
        ForeignCase::new("sensor_delay-large", vec![sensor_delay(15.0, 50)]),
        ForeignCase::new("motor_limit-small", vec![motor_limit(1300.0, 1.0)]),
        ForeignCase::new("motor_limit-large", vec![motor_limit(850.0, 1.0)]),
        ForeignCase::new("motor_limit-speedcap", vec![motor_limit(1200.0, 0.030)]),
        ForeignCase::new("hose_hysteresis-small", vec![hose_hysteresis(0.5, 1e5)]),
        ForeignCase::new("hose_hysteresis-large", vec![hose_hysteresis(1.0, 3e5)]),
        ForeignCase::new(
            "accumulator_thermal-small",
            vec![accumulator_thermal(5.0, 3.0, 20.0)],
        ),
        ForeignCase::new(
            "accumulator_thermal-large",
            vec![accumulator_thermal(0.3, 10.0, 10.0)],
        ),
        ForeignCase::new(
            "pair-friction-leakage",
            vec![friction(8.0, 2e-6, 8e5, 1.5e3), leakage(8e-11)],
        ),
        ForeignCase::new(
            "pair-backlash-accumulator_thermal",
            vec![backlash(80e-6, 2e9), accumulator_thermal(1.0, 5.0, 15.0)],
        ),
    ]
}

/// The whole CSV run log of `case` in `scenario` (realistic sensors, noise
/// seeded by `seed`). Deterministic: the same arguments give the same bytes.
pub fn log_csv(case: &ForeignCase, scenario: ForeignScenario, seed: u64) -> String {
    simulate(case, &scenario.spec(), SensorMode::Realistic, seed).to_csv()
}

/// RMS difference (noise-free signals Xo, P1, P2) between `case` and the
/// clean case in `scenario`, same seed (so the same noise).
pub fn magnitude(case: &ForeignCase, scenario: ForeignScenario, seed: u64) -> Magnitude {
    let spec = scenario.spec();
    let a = simulate(case, &spec, SensorMode::Realistic, seed);
    let b = simulate(&clean(), &spec, SensorMode::Realistic, seed);
    rms_delta(&a, &b)
}

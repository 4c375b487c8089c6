//! The fixed-point ESO stays within its stated bound of the f64 reference ESO
//! along the paper's closed-loop scenarios (docs/model.md sections 6.5 and 7).
//!
//! The MPC-ESO runs the nominal plant; at every ESO update the f64 observer is
//! fed the very same inputs (the f32 measurement and the command in force) and
//! the two states are compared against `EsoFixedGains::error_bound`.

use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use dca_core::eso::{EsoF64, EsoFixedGains};
use host_sim::model::plant::Plant;
use host_sim::model::scenario::Scenario;
use host_sim::model::sensors::SensorMode;
use host_sim::sim::{run_with, RunSpec};

fn worst_error(preset: Preset, scenario: &str, sensors: SensorMode) -> ([f64; 3], [f64; 3]) {
    let cfg = ControllerConfig::preset(preset, ControllerKind::MpcEso);
    let bound = EsoFixedGains::error_bound(&cfg.eso).expect("stable observer");
    let spec = RunSpec {
        scenario: Scenario::by_name(scenario).unwrap(),
        controller: cfg,
        plant: Plant::nominal(),
        effects: Default::default(),
        sensors,
        seed: 3,
        dt_s: 1e-4,
    };
    let mut reference = EsoF64::default();
    let mut worst = [0.0f64; 3];
    let mut updates = 0;
    run_with(&spec, |t| {
        let c = t.controller.unwrap();
        let (n_h, _) = c.periods();
        if t.k % n_h as u64 != 0 {
            return;
        }
        if t.k == 0 {
            // Bumpless start: z1 begins at the first measurement.
            reference.z1 = t.sample.xo_m as f64;
        }
        reference.update(&cfg.eso, t.sample.xo_m as f64, t.output.v_cmd_mps as f64);
        updates += 1;
        let z = c.eso_state().unwrap();
        let fixed = [
            z.z1.to_num::<f64>(),
            z.z2.to_num::<f64>(),
            z.z3.to_num::<f64>(),
        ];
        let f64s = [reference.z1, reference.z2, reference.z3];
        for i in 0..3 {
            worst[i] = worst[i].max((fixed[i] - f64s[i]).abs());
        }
    })
    .unwrap();
    assert!(updates > 900, "{updates} ESO updates");
    (worst, bound)
}

#[test]
fn fixed_point_eso_within_bound_on_paper_scenarios() {
    for preset in [Preset::Paper, Preset::Fast] {
        for scenario in ["step", "sine", "stepload", "sineload"] {
            for sensors in [SensorMode::Ideal, SensorMode::Realistic] {
                let (worst, bound) = worst_error(preset, scenario, sensors);
                println!(
                    "{:5} {scenario:8} {:9}: |dz1| {:.2e} m (bound {:.2e}), |dz2| {:.2e} m/s ({:.2e}), |dz3| {:.2e} m/s^2 ({:.2e})",
                    preset.name(), sensors.name(), worst[0], bound[0], worst[1], bound[1], worst[2], bound[2]
                );
                for i in 0..3 {
                    assert!(
                        worst[i] <= bound[i],
                        "{} {scenario} {}: z{} error {:e} > bound {:e}",
                        preset.name(),
                        sensors.name(),
                        i + 1,
                        worst[i],
                        bound[i]
                    );
                }
            }
        }
    }
}

//! Runs for the diagnosis's unit tests.

use super::run::Run;
use crate::io::runlog::RunLog;
use crate::model::effects::Effects;
use crate::model::plant::Plant;
use crate::model::rig::Rig;
use crate::model::scenario::{Piecewise, Signal};

/// An open-loop run of the rig with `effects`: the speed command and the
/// load piecewise constant (values between the switching times), logged
/// with ideal sensors at 1 ms.
pub fn open_loop_run(
    effects: Effects,
    t_end_s: f64,
    cmd: (Vec<f64>, &[f64]),
    load: (Vec<f64>, &[f64]),
) -> Run {
    let v = Signal::Piecewise(Piecewise::constants(cmd.0, cmd.1).unwrap());
    rows_run(effects, t_end_s, |k, _| v.value(k as f64 * 1e-3), load)
}

/// A run of the rig with `effects` under the load `load` (piecewise
/// constant) and the speed command `command(tick, xi_m)` at each 1 ms tick
/// (open loop, or a controller of the encoder), logged with ideal sensors
/// at every tick ([`RunLog::decimate`] gives a console capture's rows).
pub fn rows_run(
    effects: Effects,
    t_end_s: f64,
    mut command: impl FnMut(usize, f64) -> f64,
    load: (Vec<f64>, &[f64]),
) -> Run {
    let rig = Rig::new(Plant::nominal(), effects).unwrap();
    let load = Signal::Piecewise(Piecewise::constants(load.0, load.1).unwrap());
    let mut s = rig.initial_state(0.0);
    let mut text = String::from("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n");
    for k in 0..(t_end_s * 1e3).round() as usize {
        let t = k as f64 * 1e-3;
        let v = command(k, s.x.xi_m);
        let ft = load.value(t);
        text.push_str(&format!(
            "{t},0,{v},{},{},{},{},{ft}\n",
            s.x.xi_m, s.x.xo_m, s.x.p1_pa, s.x.p2_pa
        ));
        for _ in 0..10 {
            rig.step(&mut s, v, ft, 1e-4);
        }
    }
    Run::new("t".into(), RunLog::parse(&text, "t").unwrap())
}

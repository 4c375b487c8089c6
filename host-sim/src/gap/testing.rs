//! Runs for the diagnosis's unit tests.

use super::run::Run;
use crate::io::runlog::RunLog;
use crate::model::effects::Effects;
use crate::model::plant::Plant;
use crate::model::rig::Rig;
use crate::model::scenario::{Command, Piecewise, Scenario, Signal};

/// An open-loop run of the rig with `effects`: the speed command and the
/// load piecewise constant (values between the switching times), logged
/// with ideal sensors at 1 ms.
pub fn open_loop_run(
    effects: Effects,
    t_end_s: f64,
    cmd: (Vec<f64>, &[f64]),
    load: (Vec<f64>, &[f64]),
) -> Run {
    let rig = Rig::new(Plant::nominal(), effects).unwrap();
    let steps = |t: Vec<f64>, v: &[f64]| Signal::Piecewise(Piecewise::constants(t, v).unwrap());
    let sc = Scenario::new(
        "t",
        t_end_s,
        Command::OpenLoop(steps(cmd.0, cmd.1)),
        steps(load.0, load.1),
    );
    let mut s = rig.initial_state(0.0);
    let mut text = String::from("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n");
    for k in 0..(t_end_s * 1e3).round() as usize {
        let t = k as f64 * 1e-3;
        let Command::OpenLoop(v) = sc.command() else {
            unreachable!()
        };
        let v = v.value(t);
        let ft = sc.load().value(t);
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

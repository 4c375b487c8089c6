//! Automatic segmentation of a run into moves, holds, load steps and
//! reversals, from the signals every run log carries.
//!
//! Per sample, by priority:
//! 1. **load step**: within 0.5 s after the measured force changed by more than
//!    100 N (or 10 noise levels) within 20 ms;
//! 2. **reversal**: within [-0.1, +0.3] s of a sign change of the power
//!    piston's velocity (encoder, 10 ms central difference) at more than 0.5 mm/s;
//! 3. **move**: the power piston moves faster than 0.5 mm/s;
//! 4. **hold under load** (|force| > 100 N) or **hold**.
//!
//! Consecutive samples with one label form a segment.

use super::stats::noise_sigma;
use crate::io::runlog::RunLog;

/// Segment labels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Label {
    /// After a load change.
    LoadStep,
    /// Around a change of direction.
    Reversal,
    /// The power piston moving.
    Move,
    /// At rest under a load.
    HoldUnderLoad,
    /// At rest.
    Hold,
}

impl Label {
    /// Human-readable name (the `label` of the gap report).
    pub fn name(self) -> &'static str {
        match self {
            Self::LoadStep => "load step",
            Self::Reversal => "reversal",
            Self::Move => "move",
            Self::HoldUnderLoad => "hold under load",
            Self::Hold => "hold",
        }
    }
}

/// A stretch of a run with one label: samples [i0, i1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// What happens there.
    pub label: Label,
    /// First sample.
    pub i0: usize,
    /// One past the last sample.
    pub i1: usize,
}

/// Speed above which the piston counts as moving, m/s.
pub const MOVE_MPS: f64 = 0.5e-3;
/// Force above which a hold is under load, N.
pub const LOAD_N: f64 = 100.0;

/// The label of every sample.
pub fn labels(log: &RunLog) -> Vec<Label> {
    let n = log.len();
    let dt = log.dt_s().max(1e-6);
    let w = ((0.010 / dt).round() as usize).max(1);
    // Power-piston velocity from the encoder, central difference over 2w samples.
    let vel: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(w), (i + w).min(n - 1));
            if b > a {
                (log.xi_m[b] - log.xi_m[a]) / ((b - a) as f64 * dt)
            } else {
                0.0
            }
        })
        .collect();
    let mut label: Vec<Label> = (0..n)
        .map(|i| {
            if vel[i].abs() > MOVE_MPS {
                Label::Move
            } else if log.ft_n[i].abs() > LOAD_N {
                Label::HoldUnderLoad
            } else {
                Label::Hold
            }
        })
        .collect();
    let mark = |label: &mut Vec<Label>, t0: f64, t1: f64, l: Label| {
        let i0 = ((t0 / dt).floor().max(0.0)) as usize;
        let i1 = (((t1 / dt).ceil()) as usize).min(n);
        for x in label.iter_mut().take(i1).skip(i0) {
            if l < *x {
                *x = l;
            }
        }
    };
    // Reversals: sign changes of the velocity while moving.
    let mut last_sign = 0.0f64;
    for (i, v) in vel.iter().enumerate() {
        if v.abs() > MOVE_MPS {
            let s = v.signum();
            if last_sign != 0.0 && s != last_sign {
                let t = i as f64 * dt;
                mark(&mut label, t - 0.1, t + 0.3, Label::Reversal);
            }
            last_sign = s;
        }
    }
    // Load steps: force changes within 20 ms.
    let thr = LOAD_N.max(10.0 * noise_sigma(&log.ft_n));
    let k = ((0.020 / dt).round() as usize).max(1);
    let mut i = k;
    while i < n {
        if (log.ft_n[i] - log.ft_n[i - k]).abs() > thr {
            let t = (i - k) as f64 * dt;
            mark(&mut label, t, t + 0.5, Label::LoadStep);
            i += ((0.5 / dt) as usize).max(1);
        } else {
            i += 1;
        }
    }
    label
}

/// The segments of a run (consecutive samples with one label).
pub fn segments(log: &RunLog) -> Vec<Segment> {
    let l = labels(log);
    let mut out: Vec<Segment> = Vec::new();
    for (i, x) in l.iter().enumerate() {
        match out.last_mut() {
            Some(s) if s.label == *x => s.i1 = i + 1,
            _ => out.push(Segment {
                label: *x,
                i0: i,
                i1: i + 1,
            }),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log(n: usize, xi: impl Fn(f64) -> f64, ft: impl Fn(f64) -> f64) -> RunLog {
        let mut l = RunLog::default();
        for i in 0..n {
            let t = i as f64 * 1e-3;
            l.t_s.push(t);
            l.xi_m.push(xi(t));
            l.ft_n.push(ft(t));
            for v in [
                &mut l.ref_m,
                &mut l.vcmd_mps,
                &mut l.xo_m,
                &mut l.p1_pa,
                &mut l.p2_pa,
            ] {
                v.push(0.0);
            }
        }
        l
    }

    #[test]
    fn move_hold_load_step_and_hold_under_load() {
        // Move 0-1 s at 10 mm/s, hold, 800 N from 3 s.
        let l = log(
            6000,
            |t| 0.01 * t.min(1.0),
            |t| if t >= 3.0 { 800.0 } else { 0.0 },
        );
        let s = segments(&l);
        let names: Vec<&str> = s.iter().map(|s| s.label.name()).collect();
        assert_eq!(
            names,
            ["move", "hold", "load step", "hold under load"],
            "{s:?}"
        );
        let step = s.iter().find(|s| s.label == Label::LoadStep).unwrap();
        assert!(
            (step.i0 as f64 - 2980.0).abs() <= 1.0 && (step.i1 as f64 - 3480.0).abs() <= 2.0,
            "{step:?}"
        );
    }

    #[test]
    fn reversal_between_moves() {
        // Out and back: a triangle in Xi with its peak at 1 s.
        let l = log(2000, |t| 0.01 * (1.0 - (t - 1.0).abs()), |_| 0.0);
        let s = segments(&l);
        let rev = s
            .iter()
            .find(|s| s.label == Label::Reversal)
            .expect("reversal");
        assert!(rev.i0 >= 880 && rev.i0 <= 910, "{rev:?}");
        assert!(rev.i1 >= 1290 && rev.i1 <= 1310, "{rev:?}");
    }
}

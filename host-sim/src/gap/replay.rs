//! Replay: the model driven open loop by a run log's recorded inputs.
//!
//! Inputs are the recorded drive command `vcmd_mps` (through the servo model,
//! so the servo and the ball screw are part of what is tested) and the
//! recorded load `ft_n` (its noise reduced by a running median), each held
//! over one log interval of one controller tick (the firmware holds its
//! command for a control period; the simulator's commands change only at
//! controller ticks, which fall on the log grid). On longer rows the command
//! is corrected within a bound toward the row's mean the encoder tells
//! ([`RowCommands`]) and the load interpolated between rows, held across a
//! step. The model starts at rest at
//! the first encoder count and the measured position and load averaged over
//! the first 20 ms while the encoder has not moved. The outputs are what ideal sensors
//! (with the candidate `sensor_delay`, if any, named or in its general family)
//! would have reported at the log instants, for the channels the gap compares.
//! Under a candidate `sensor_calibration` (named or general) the replay reads
//! through its map, and starts from (and, for the force sensor, is driven by)
//! the true values its inverse gives of the recorded ones.

use crate::io::runlog::{RunLog, StepRange};
use crate::model::effects::CalChannel;
use crate::model::rig::Rig;
use crate::model::sensors::{Readings, SensorMode, Sensors};

/// The log steps the diagnosis replays. Rows of at most 0.01 s: the
/// diagnosis is validated on rows of 1 and 10 ms (docs/gap.md; 10 ms is
/// the board console's fastest capture), and the gap of a clean run grows
/// with the row step (measured on four clean fit/check pairs: check runs
/// about 0.4 at 1 ms, 0.7 at 10 ms, 1.0 to 1.4 at 20 ms, where one pair was
/// called `unexplained`); beyond 23 ms the model's 16-22 Hz hydraulic mode
/// (docs/model.md section 4.3) lies above half the row rate and cannot show
/// at all. Rows of at least 1e-4 s, the plant's integration step: finer
/// ones add only work (the sensor delay lines and the load's median window
/// grow as 1 / step).
pub const LOG_STEPS: StepRange = StepRange {
    min_dt_s: 1e-4,
    max_dt_s: 0.01,
    why: "the gap diagnosis (validated on rows of 1 to 10 ms: at 20 ms a clean run's gap \
          already reaches the verdict's threshold; 1e-4 s is the plant's integration step)",
};

/// The most plant steps the replay takes over one log row; a longer row (or
/// a step below [`LOG_STEPS`]) is not replayed: every channel is NaN, as
/// after a divergence. The largest
/// step of [`LOG_STEPS`] at the smallest plant step the diagnosis uses
/// (5e-4 s, scaled by at least 0.01 for a stiffened line) takes 2000.
pub const MAX_SUB_STEPS: usize = 10_000;

/// The channels compared, in this order everywhere in the diagnosis.
pub const CHANNELS: [&str; 4] = ["xo_m", "xi_m", "p1_pa", "p2_pa"];

/// Measured values of the compared channels.
pub fn measured(log: &RunLog) -> [&[f64]; 4] {
    [&log.xo_m, &log.xi_m, &log.p1_pa, &log.p2_pa]
}

/// The replayed channels at the log instants (NaN after a divergence).
#[derive(Clone, Debug, PartialEq)]
pub struct Replay {
    /// Xo, Xi, P1, P2 in [`CHANNELS`] order.
    pub ch: [Vec<f64>; 4],
}

/// Replay `log` on `rig` with plant steps of at most `max_dt_s`.
pub fn replay(log: &RunLog, rig: &Rig, max_dt_s: f64) -> Replay {
    let load = filtered_load(log);
    replay_with_load(log, &load, rig, max_dt_s)
}

/// The recorded load with its sensor noise reduced: a running median over
/// 10 ms (11 samples at 1 ms; keeps the steps of the load, removes the noise
/// that would otherwise drive the replayed pressures). On 10 ms rows the
/// window holds one row: the load is used as recorded.
pub fn filtered_load(log: &RunLog) -> Vec<f64> {
    let n = log.len();
    // (At most the log's length: a window of more rows is the same window.)
    let half = half_window(log.dt_s()).min(n);
    (0..n)
        .map(|i| super::stats::median(&log.ft_n[i.saturating_sub(half)..(i + half + 1).min(n)]))
        .collect()
}

/// Rows either side of the load's running median: 5 ms of the log (five
/// rows at 1 ms; none at 10 ms, where a median over 11 rows would start a
/// run under a rising load from the median of its first 60 ms).
fn half_window(dt_s: f64) -> usize {
    if dt_s > 0.0 {
        // (The relative tolerance keeps 1 ms rows written as 0.0009999...
        // at five.)
        (LOAD_MEDIAN_HALF_S / dt_s * (1.0 + 1e-6)).floor() as usize
    } else {
        5
    }
}

/// Half the span of the load's running median, s.
const LOAD_MEDIAN_HALF_S: f64 = 0.005;

/// Replay with a given load signal (see [`filtered_load`]).
pub fn replay_with_load(log: &RunLog, load: &[f64], rig: &Rig, max_dt_s: f64) -> Replay {
    let mut ch: [Vec<f64>; 4] = Default::default();
    for c in ch.iter_mut() {
        c.reserve(log.len());
    }
    replay_visit(log, load, rig, max_dt_s, |_, v| {
        for (c, x) in ch.iter_mut().zip(v) {
            c.push(x);
        }
        true
    });
    Replay { ch }
}

/// Replay with a given load signal, handing each log instant's channels
/// (index, [`CHANNELS`] order; NaN after a divergence) to `visit`, which
/// stops the replay by returning false.
pub fn replay_visit(
    log: &RunLog,
    load: &[f64],
    rig: &Rig,
    max_dt_s: f64,
    mut visit: impl FnMut(usize, [f64; 4]) -> bool,
) {
    let n = log.len();
    if n == 0 {
        return;
    }
    let log_dt = log.dt_s();
    // Plant steps per row; rows that would take more than MAX_SUB_STEPS, or
    // finer than LOG_STEPS allows (the sensors' delay lines grow as
    // 1 / step), are not replayed: the work stays bounded whatever the log.
    let sub_f = (log_dt / (max_dt_s * rig.step_scale())).ceil().max(1.0);
    let replayable = log_dt >= LOG_STEPS.min_dt_s && sub_f <= MAX_SUB_STEPS as f64;
    let sub = if replayable { sub_f as usize } else { 1 };
    let h = log_dt / sub as f64;
    // Start at rest at the encoder's first count (it has no noise), with the
    // LVDT and the load averaged over the samples of the first 20 ms in
    // which the encoder has not yet moved by 5 um (at least the first): a
    // single LVDT sample is 13 um off, and a median of its 29 um quantisation
    // steps is biased; a mean is dithered by the noise. (Xo lags Xi through
    // the hoses, so those few micrometres of motion barely reach it.)
    let head = ((0.02 / log_dt.max(1e-6)) as usize).clamp(1, n);
    let xi0 = log.xi_m[0];
    let still = log.xi_m[..head]
        .iter()
        .take_while(|x| (*x - xi0).abs() < 5e-6)
        .count()
        .max(1);
    let start = |v: &[f64]| super::stats::mean(&v[..still.min(v.len())]);
    let (mut ft0, mut xi0, mut xo0) = (start(load), xi0, start(&log.xo_m));
    let (cal, map) = (rig.effects().sensor_calibration, rig.effects().sensor_map);
    // The true value of a recorded one on the calibrated channel.
    let truth = |ch: CalChannel, v: f64| match (cal, map) {
        (Some(c), _) if c.channel == ch => c.invert(v),
        (_, Some(m)) if m.channel == ch => m.invert(v),
        _ => v,
    };
    ft0 = truth(CalChannel::Ft, ft0);
    xi0 = truth(CalChannel::Xi, xi0);
    xo0 = truth(CalChannel::Xo, xo0);
    let mut s = rig.rest_state(ft0, xi0, xo0);
    if !replayable {
        for k in 0..n {
            if !visit(k, [f64::NAN; 4]) {
                return;
            }
        }
        return;
    }
    let mut sensors = Sensors::new(SensorMode::Ideal, 0).with_effects(rig.effects(), log_dt);
    let mut diverged = false;
    let rows = RowCommands::of(log, rig.plant().params().tau_m_s);
    let servo_alone = rig.servo_alone();
    // On rows longer than a controller tick the load is interpolated between
    // the rows: held, it would lag by half a row (5 ms at 10 ms, a quarter of
    // the hydraulic mode's period); on 1 ms rows it is held, as recorded.
    // A change from one row to the next beyond `load_jump_n` is a step (a
    // load applied or released): held, it takes effect at the next row, as
    // the recorded one did; a ramp to it would start it half a row early.
    let interpolate = log_dt > ONE_TICK_ROW_S;
    let load_jump_n = if interpolate { load_jump(load) } else { 0.0 };
    for (k, (&ft, &recorded)) in load.iter().zip(&log.vcmd_mps).enumerate() {
        let ft = truth(CalChannel::Ft, ft);
        if diverged {
            if !visit(k, [f64::NAN; 4]) {
                return;
            }
            continue;
        }
        let x = s.x;
        let r = sensors.read(&Readings {
            xi_m: x.xi_m,
            xo_m: x.xo_m,
            p1_pa: x.p1_pa,
            p2_pa: x.p2_pa,
            ft_n: ft,
        });
        if !visit(k, [r.xo_m, r.xi_m, r.p1_pa, r.p2_pa]) {
            return;
        }
        // The load between this row and the next, at each plant step's
        // middle (held where it jumps, and on rows of one tick).
        let next = load
            .get(k + 1)
            .map(|f| truth(CalChannel::Ft, *f))
            .filter(|f| interpolate && (f - ft).abs() <= load_jump_n)
            .unwrap_or(ft);
        let load_at = |j: usize| {
            if next == ft {
                ft
            } else {
                ft + (next - ft) * (j as f64 + 0.5) / sub as f64
            }
        };
        let mut vcmd = recorded;
        if let (Some(rows), Some(&xi_next)) = (&rows, log.xi_m.get(k + 1)) {
            // Where the servo ignores the hydraulics, the probe steps it
            // alone (the same Xi, bit for bit).
            let xi_end = if servo_alone {
                let mut m = (s.x.xi_m, s.x.vi_mps);
                for _ in 0..sub {
                    m = rig.step_servo(m, recorded, h);
                }
                m.0
            } else {
                let mut probe = s;
                for j in 0..sub {
                    rig.step(&mut probe, recorded, load_at(j), h);
                }
                probe.x.xi_m
            };
            let miss = truth(CalChannel::Xi, xi_next) - xi_end;
            let b = rows.bound[k];
            vcmd += (miss / rows.travel_per_mps).clamp(-b, b);
        }
        for j in 0..sub {
            rig.step(&mut s, vcmd, load_at(j), h);
        }
        diverged = !s.is_finite();
    }
}

/// Rows longer than this hold several of the controller's commands (it
/// ticks at 1 ms; docs/interfaces.md section 1), of which the log keeps the
/// first.
pub const ONE_TICK_ROW_S: f64 = 1.5e-3;

/// Bound of the command's correction, in robust standard deviations of one
/// recorded sample about its row's mean ([`RowCommands::bound`]): that
/// scatter (the controller's response to sensor noise) passes, a systematic
/// departure (a servo that cannot follow) keeps all but this much of its
/// size.
pub const CORRECTION_SIGMAS: f64 = 3.0;

/// Robust standard deviations of the load's change between rows beyond
/// which a change is a step ([`load_jump`]).
const LOAD_JUMP_SIGMAS: f64 = 10.0;

/// The change of the load between two rows beyond which it is a step and not
/// a smooth change: [`LOAD_JUMP_SIGMAS`] robust standard deviations of the
/// changes (sensor noise and the smooth loads' own change per row).
fn load_jump(load: &[f64]) -> f64 {
    let d: Vec<f64> = load
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| d.is_finite())
        .collect();
    LOAD_JUMP_SIGMAS * super::stats::mad_sigma(&d)
}

/// How the replay holds the drive command over rows longer than one
/// controller tick.
///
/// On rows of one tick (1 ms) the replay holds the recorded command. On
/// longer rows (a board capture at 10 ms keeps one command in ten) the
/// recorded one is a single sample of a command the controller changed at
/// every tick, largely in response to sensor noise, and around a step it
/// may precede the controller's reaction; held over the row it drives the
/// replayed encoder off (a clean rig under `cmpc-eso` `limit` at 10 ms: fit
/// gap 114 against 0.4 at 1 ms). The encoder, which has no noise, tells the
/// row's mean command. At each row the replay first steps a copy of its
/// model with the recorded command; the command it holds is the recorded
/// one plus the correction that takes a first-order speed loop of the
/// model's time constant to the next row's recorded position, bounded by
/// [`RowCommands::bound`]. The correction is solved on the model being
/// replayed: a candidate whose servo explains the encoder (a force or
/// speed limit) needs none, the nominal model needs one as large as the
/// bound allows, so the servo's departure still shows.
#[derive(Clone, Debug, PartialEq)]
pub struct RowCommands {
    /// Bound of each row's correction, m/s: [`CORRECTION_SIGMAS`] robust
    /// standard deviations of the corrections the nominal speed loop needs
    /// row by row (the scatter of one sample about its row's mean), at most
    /// the command's own scatter from row to row or the encoder's
    /// resolution over a row, whichever is larger; widened by the
    /// largest jump of the recorded command into or out of the row (where a
    /// step reached the controller within the row, the unrecorded commands
    /// lie anywhere between).
    pub bound: Vec<f64>,
    /// Travel over a row per m/s of held command: `dt - tau (1 - e^(-dt/tau))`.
    pub travel_per_mps: f64,
}

impl RowCommands {
    /// The bounds for `log` and a speed loop of time constant `tau_m_s`;
    /// `None` on rows of one tick, or where the log tells nothing.
    pub fn of(log: &RunLog, tau_m_s: f64) -> Option<Self> {
        let dt = log.dt_s();
        let n = log.len();
        if dt <= ONE_TICK_ROW_S || n < 3 || tau_m_s.is_nan() || tau_m_s <= 0.0 {
            return None;
        }
        let decay = (-dt / tau_m_s).exp();
        let (from_v0, from_u) = (tau_m_s * (1.0 - decay), dt - tau_m_s * (1.0 - decay));
        let u = &log.vcmd_mps;
        // The scatter of one recorded sample about its row's mean: the
        // corrections that take the nominal speed loop through the recorded
        // encoder row by row (robust: a servo that departs on fewer than
        // half of the rows does not widen it).
        let mut v = 0.0;
        let mut abs = Vec::with_capacity(n - 1);
        for (w, uk) in log.xi_m.windows(2).zip(u) {
            let m = (w[1] - w[0] - v * from_v0) / from_u;
            abs.push((m - uk).abs());
            v = m + (v - m) * decay;
        }
        abs.retain(|d| d.is_finite());
        let from_encoder = super::stats::mad_sigma(&abs);
        // ... but no wider than the command's own scatter from row to row
        // (its white noise level, from its second differences) or, where
        // the command is smooth, the encoder's resolution over a row: an
        // encoder that departs from the command on most rows (a stalled
        // drive) must not widen its own excuse.
        let own = super::stats::noise_sigma(u);
        let count_m = log
            .xi_m
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .filter(|d| *d > 0.0 && d.is_finite())
            .fold(f64::INFINITY, f64::min);
        let resolution = if count_m.is_finite() {
            count_m / from_u
        } else {
            0.0
        };
        let sigma = from_encoder.min(own.max(resolution));
        if !sigma.is_finite() {
            return None;
        }
        let bound = (0..n)
            .map(|k| {
                let into = if k > 0 { (u[k] - u[k - 1]).abs() } else { 0.0 };
                let out = if k + 1 < n {
                    (u[k + 1] - u[k]).abs()
                } else {
                    0.0
                };
                CORRECTION_SIGMAS * sigma + into.max(out)
            })
            .collect();
        Some(Self {
            bound,
            travel_per_mps: from_u,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_load_median_spans_five_ms_either_side() {
        for (dt, half) in [
            (0.001, 5),
            (0.000_999_999_9, 5),
            (0.001_000_000_1, 5),
            (0.002, 2),
            (0.005, 1),
            (0.01, 0),
        ] {
            assert_eq!(half_window(dt), half, "dt {dt}");
        }
    }

    /// A log built in code with a step the reader refuses is not replayed
    /// (NaN at every row) instead of taking 1e300 plant steps per row or
    /// allocating a delay line of 1e300 samples.
    #[test]
    fn a_step_the_model_cannot_replay_gives_nan_at_once() {
        let rig = Rig::new(crate::model::plant::Plant::nominal(), Default::default()).unwrap();
        for dt in [1e303, 1e-300] {
            let mut text = String::from("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n");
            for k in 0..5 {
                text += &format!("{:e},0,0.01,0,0,0,0,0\n", k as f64 * dt);
            }
            let log = RunLog::parse(&text, "far.csv").unwrap();
            let r = replay(&log, &rig, 5e-4);
            assert!(r.ch.iter().all(|c| c.len() == 5), "dt {dt}");
            assert!(r.ch.iter().flatten().all(|v| v.is_nan()), "dt {dt}");
        }
        // The largest step the reader lets through is replayed.
        let mut text = String::from("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n");
        for k in 0..5 {
            text += &format!("{:.2},0,0.01,0,0,0,0,0\n", k as f64 * LOG_STEPS.max_dt_s);
        }
        let log = RunLog::parse_with(&text, "slow.csv", &LOG_STEPS).unwrap();
        let r = replay(&log, &rig, 5e-4);
        assert!(r.ch.iter().flatten().all(|v| v.is_finite()));
        assert!(r.ch[1][4] > r.ch[1][0], "the encoder moves: {:?}", r.ch[1]);
    }

    /// A 1 ms log of `rig` driven by a command that changes at every tick
    /// (a slow sine, noise of 1 mm/s, a step at 0.5 s), no load, ideal
    /// sensors.
    fn ticked_log(rig: &Rig) -> RunLog {
        let mut s = rig.initial_state(0.0);
        let mut text = String::from("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n");
        let mut seed = 7u64;
        for k in 0..1500 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let noise = ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 3.5e-3;
            let t = k as f64 * 1e-3;
            let step = if t >= 0.5 { 0.03 } else { 0.0 };
            let u = 0.01 * (2.0 * t).sin() + step + noise;
            let x = s.x;
            text += &format!(
                "{t:.3},0,{u:e},{:e},{:e},{:e},{:e},0\n",
                x.xi_m, x.xo_m, x.p1_pa, x.p2_pa
            );
            for _ in 0..10 {
                rig.step(&mut s, u, 0.0, 1e-4);
            }
        }
        RunLog::parse(&text, "ticked.csv").unwrap()
    }

    fn nominal() -> Rig {
        Rig::new(crate::model::plant::Plant::nominal(), Default::default()).unwrap()
    }

    /// A drive whose speed is capped at 25 mm/s (the command after the step
    /// asks for 30 to 40).
    fn capped() -> Rig {
        let mut e = crate::model::effects::Effects::NONE;
        e.parse_arg("motor_limit:force_max_n=1e6,speed_max_mps=0.025")
            .unwrap();
        Rig::new(crate::model::plant::Plant::nominal(), e).unwrap()
    }

    /// The largest distance of the replayed encoder from the recorded one.
    fn encoder_miss(log: &RunLog, rig: &Rig) -> f64 {
        let r = replay(log, rig, 5e-4);
        r.ch[1]
            .iter()
            .zip(&log.xi_m)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn one_tick_rows_hold_the_recorded_command() {
        assert_eq!(RowCommands::of(&ticked_log(&nominal()), 0.01), None);
    }

    /// On 10 ms rows the recorded samples, held, drive a first-order speed
    /// loop off by millimetres (their noise's random walk and the step they
    /// precede); the replay's held means keep the encoder on the recorded
    /// one.
    #[test]
    fn ten_ms_rows_hold_the_row_s_mean_command() {
        let log = ticked_log(&nominal()).decimate(10);
        let (tau, dt) = (0.01f64, 0.01);
        let (mut v, mut x, mut raw) = (0.0, log.xi_m[0], 0.0f64);
        for (u, xi) in log.vcmd_mps.iter().zip(&log.xi_m) {
            raw = raw.max((x - xi).abs());
            let d = (-dt / tau).exp();
            x += v * tau * (1.0 - d) + u * (dt - tau * (1.0 - d));
            v = u + (v - u) * d;
        }
        let held = encoder_miss(&log, &nominal());
        assert!(
            held < 2e-6 && raw > 20.0 * held,
            "raw {raw:e}, held {held:e}"
        );
    }

    /// A servo that cannot follow still shows on 10 ms rows: the nominal
    /// model's encoder runs ahead of the recorded one, as far as the
    /// correction's bound lets it, while the model with the speed cap
    /// replays it.
    #[test]
    fn a_servo_that_cannot_follow_still_shows_on_10_ms_rows() {
        let log = ticked_log(&capped()).decimate(10);
        let (nominal, capped) = (
            encoder_miss(&log, &nominal()),
            encoder_miss(&log, &capped()),
        );
        assert!(
            nominal > 1e-3 && capped < 5e-6,
            "nominal {nominal:e}, capped {capped:e}"
        );
    }

    #[test]
    fn a_ramp_on_10_ms_rows_is_used_as_recorded() {
        // A load ramping from the first row: a median over 11 rows would
        // start it at the median of its first six (60 ms).
        let mut text = String::from("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n");
        for k in 0..20 {
            text += &format!("{:.3},0,0,0,0,0,0,{}\n", k as f64 * 0.01, 300 + 6 * k);
        }
        let log = RunLog::parse(&text, "ramp.csv").unwrap();
        assert_eq!(filtered_load(&log), log.ft_n);
        // On 1 ms rows the median still removes spikes (one row in four).
        let mut text = String::from("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n");
        for k in 0..40 {
            let spike = if k % 4 == 1 { 40.0 } else { 0.0 };
            text += &format!("{:.3},0,0,0,0,0,0,{}\n", k as f64 * 0.001, 300.0 + spike);
        }
        let log = RunLog::parse(&text, "spiky.csv").unwrap();
        assert!(filtered_load(&log).iter().all(|&v| v == 300.0));
    }
}

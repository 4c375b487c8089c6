//! One controller interface over MPC-ESO, MPC, PID and fuzzy PID, with the
//! multi-rate schedule of docs/model.md section 6.1.
//!
//! [`ControllerConfig`] holds the parameters (physical, as a user sets them);
//! [`Controller::new`] designs from it once (f64, slow, allocation-free) and
//! the resulting [`Controller`] is called once per base tick through
//! [`Controller::step`], which uses only precomputed numbers. A parameter
//! change is a new configuration and a new controller, never a mutation
//! hidden in a step.
//!
//! Every base tick, in this order (section 6.1):
//! 1. check the sample and the reference (non-finite: safe command, flag);
//! 2. TD update if `k mod n_h == 0` (MPC-ESO only);
//! 3. MPC / PID update if `k mod n_c == 0`, using the ESO state *before* this
//!    tick's ESO update;
//! 4. ESO update if `k mod n_h == 0` with y = Xo and u = the command now in force.
//!
//! Start-up is bumpless: on the first tick the commanded power-piston position
//! starts at the measured Xi and the ESO's z1 and the TD's v1 at the measured
//! Xo (all zero in the scenarios of docs/model.md, which start at rest at 0).

use crate::cmpc::{Cmpc, CmpcGains, CmpcInput, CmpcParams};
use crate::design::{DesignError, MpcParams};
use crate::eso::{EsoError, EsoFixed, EsoFixedGains, EsoParams};
use crate::fuzzy::{FuzzyParams, FuzzyPid};
use crate::fxp::{self, Pos, Vel, POS_FRAC, VEL_FRAC};
use crate::mpc::{clamp, Limits, Mpc, MpcGains, Observed};
use crate::params::PlantParams;
use crate::pid::{Pid, PidParams};
use crate::td::{Td, TdParams};

/// The control laws the core offers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControllerKind {
    /// MPC on the augmented model with the ESO's observed state and the TD.
    MpcEso,
    /// MPC with its own open-loop model state (Wang 2009).
    Mpc,
    /// Velocity-output PI(D) with anti-windup.
    Pid,
    /// PID with Mamdani fuzzy gain scheduling.
    FuzzyPid,
    /// MPC-ESO whose moves solve the constrained quadratic program (speed,
    /// acceleration and stroke), with load feedforward and reference preview
    /// ([`crate::cmpc`]; beyond the paper).
    CmpcEso,
}

impl ControllerKind {
    /// All kinds: the paper's comparison in its order, then the project's
    /// constrained MPC-ESO.
    pub const ALL: [Self; 5] = [
        Self::MpcEso,
        Self::Mpc,
        Self::Pid,
        Self::FuzzyPid,
        Self::CmpcEso,
    ];

    /// The command-line and log name (`mpc-eso`, `mpc`, `pid`, `fuzzy-pid`).
    pub fn name(self) -> &'static str {
        match self {
            Self::MpcEso => "mpc-eso",
            Self::Mpc => "mpc",
            Self::Pid => "pid",
            Self::FuzzyPid => "fuzzy-pid",
            Self::CmpcEso => "cmpc-eso",
        }
    }

    /// Parse a name given by [`Self::name`].
    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == s)
    }
}

/// Named parameter presets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Preset {
    /// docs/model.md section 6.3: Ts = 0.1 s, h = 0.006 s, r_w = 33.
    Paper,
    /// docs/model.md section 10: Ts = 0.01 s, h = 0.001 s, r_w = 300.
    Fast,
    /// "fast", with the constrained MPC-ESO tuned for the rig at its limits
    /// ([`CmpcParams::LIMIT`]; docs/interfaces.md section 7).
    Limit,
}

impl Preset {
    /// Every preset.
    pub const ALL: [Self; 3] = [Self::Paper, Self::Fast, Self::Limit];

    /// `paper`, `fast` or `limit`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::Fast => "fast",
            Self::Limit => "limit",
        }
    }

    /// Parse a name given by [`Self::name`].
    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == s)
    }
}

/// Everything a controller is designed from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerConfig {
    /// Which law runs.
    pub kind: ControllerKind,
    /// Base (control) tick period, s: 1e-3 on the board and in host-sim's
    /// commands; [`Self::preset`] gives 1e-4, a finer tick for studies.
    pub base_dt_s: f64,
    /// Physical parameters the prediction model is built from.
    pub plant: PlantParams,
    /// Plain MPC design.
    pub mpc: MpcParams,
    /// MPC-ESO design.
    pub mpc_eso: MpcParams,
    /// Constrained MPC-ESO design.
    pub cmpc: CmpcParams,
    /// Observer.
    pub eso: EsoParams,
    /// Tracking differentiator (its `h_s` is the ESO's step).
    pub td: TdParams,
    /// PI(D) baseline.
    pub pid: PidParams,
    /// Fuzzy PID.
    pub fuzzy: FuzzyParams,
    /// Speed and stroke limits.
    pub limits: Limits,
    /// Largest plausible |Xo|, m; a larger reading is clamped and flagged.
    pub xo_plausible_m: f32,
}

impl ControllerConfig {
    /// A preset for one controller, at a base tick of 1e-4 s (a study's tick
    /// finer than the board's 1 ms: set `base_dt_s` to run as the board does).
    pub fn preset(preset: Preset, kind: ControllerKind) -> Self {
        let plant = PlantParams::NOMINAL;
        let mut cfg = Self {
            kind,
            base_dt_s: 1.0e-4,
            plant,
            mpc: MpcParams {
                np: 6,
                nc: 2,
                ts_s: 0.1,
                rw: 33.0,
            },
            mpc_eso: MpcParams {
                np: 8,
                nc: 3,
                ts_s: 0.1,
                rw: 33.0,
            },
            cmpc: CmpcParams::LIMIT,
            eso: EsoParams::PAPER,
            td: TdParams::PAPER,
            pid: PidParams::PAPER,
            fuzzy: FuzzyParams::PAPER,
            limits: Limits::from_plant(&plant),
            xo_plausible_m: 1.0,
        };
        if preset != Preset::Paper {
            for m in [&mut cfg.mpc, &mut cfg.mpc_eso] {
                m.ts_s = 0.01;
                m.rw = 300.0;
            }
            cfg.eso.h_s = 0.001;
            cfg.td.h_s = 0.001;
            cfg.pid.ts_s = 0.01;
            cfg.fuzzy.base.ts_s = 0.01;
        }
        cfg
    }

    /// The MPC parameters of the selected kind (plain or ESO variant; the
    /// constrained MPC-ESO's own are [`Self::cmpc`]).
    pub fn active_mpc(&self) -> MpcParams {
        match self.kind {
            ControllerKind::Mpc => self.mpc,
            _ => self.mpc_eso,
        }
    }
}

/// Why a configuration was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConfigError {
    /// The MPC design failed.
    Design(DesignError),
    /// The observer parameters are invalid.
    Eso(EsoError),
    /// TD parameters not finite and positive.
    Td,
    /// PID or fuzzy parameters invalid.
    Pid,
    /// Limits invalid.
    Limits,
    /// Base tick not positive, or a task period shorter than the base tick or
    /// longer than 2^31 base ticks.
    Schedule,
}

impl ConfigError {
    /// A short human-readable reason.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Design(d) => d.as_str(),
            Self::Eso(EsoError::Gain) => "ESO gains or step out of range",
            Self::Eso(EsoError::Fal) => "ESO alpha must be in (0, 1] and delta in (0, 8) m",
            Self::Td => "TD parameters must be finite and > 0",
            Self::Pid => "PID gains must be finite and >= 0, Ts > 0",
            Self::Limits => "limits must be finite with v_max > 0 and x_min < x_max",
            Self::Schedule => "task periods must be whole multiples of the base tick",
        }
    }
}

/// One sample of the sensors, SI units (built the same way by the firmware,
/// the simulator and the HIL loop).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Actuating piston position (LVDT), m.
    pub xo_m: f32,
    /// Power piston position (motor encoder), m.
    pub xi_m: f32,
    /// Line-1 pressure, gauge, Pa.
    pub p1_pa: f32,
    /// Line-2 pressure, gauge, Pa.
    pub p2_pa: f32,
    /// Load force, N.
    pub ft_n: f32,
}

/// Status bits of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Flags(pub u8);

impl Flags {
    /// The position measurement or the reference was NaN or infinite: the
    /// command is 0 and no controller state was updated.
    pub const NON_FINITE_INPUT: u8 = 1 << 0;
    /// The position measurement was outside the plausible range and clamped.
    pub const OUT_OF_RANGE: u8 = 1 << 1;
    /// The reference was outside the stroke and clamped to it.
    pub const REF_CLAMPED: u8 = 1 << 2;
    /// A speed or stroke limit was active at the last controller update.
    pub const SATURATED: u8 = 1 << 3;
    /// The law produced a non-finite value: the command is 0.
    pub const NON_FINITE_OUTPUT: u8 = 1 << 4;

    /// True if any of `bits` is set.
    pub fn has(self, bits: u8) -> bool {
        self.0 & bits != 0
    }

    /// True if a bit that makes the command a safe stop is set.
    pub fn is_error(self) -> bool {
        self.has(Self::NON_FINITE_INPUT | Self::NON_FINITE_OUTPUT)
    }
}

/// Result of one base tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Output {
    /// Drive speed command, m/s, within +-v_max.
    pub v_cmd_mps: f32,
    /// Status of this tick.
    pub flags: Flags,
}

// No allocation in the core: the largest law (the constrained MPC-ESO's
// gains, ~0.5 KB) sets the size of every controller value, by design.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug)]
enum Law {
    MpcEso {
        gains: MpcGains,
        eso_gains: EsoFixedGains,
        b0: f32,
        mpc: Mpc,
        eso: EsoFixed,
        td: Td,
        td_params: TdParams,
    },
    Mpc {
        gains: MpcGains,
        mpc: Mpc,
    },
    Pid {
        params: PidParams,
        pid: Pid,
    },
    Fuzzy {
        params: FuzzyParams,
        fuzzy: FuzzyPid,
    },
    CmpcEso {
        gains: CmpcGains,
        eso_gains: EsoFixedGains,
        b0: f32,
        cmpc: Cmpc,
        eso: EsoFixed,
    },
}

/// A designed controller with its run-time state.
#[derive(Clone, Copy, Debug)]
pub struct Controller {
    kind: ControllerKind,
    law: Law,
    limits: Limits,
    xo_plausible_m: f32,
    /// ESO/TD period in base ticks.
    n_h: u32,
    /// MPC/PID period in base ticks.
    n_c: u32,
    /// Base tick index k.
    k: u64,
    /// `k mod n_h`, kept as a counter: no 64-bit division per tick.
    phase_h: u32,
    /// `k mod n_c`.
    phase_c: u32,
    /// Command in force.
    v_cmd_mps: f32,
    /// Saturation seen at the last controller update.
    saturated: bool,
    started: bool,
}

/// `(k + 1) mod n` from `phase = k mod n` and `k_next = k + 1` (wrapping): the
/// counter restarts with k when k wraps around.
#[inline]
fn next_phase(phase: u32, n: u32, k_next: u64) -> u32 {
    if phase + 1 >= n || k_next == 0 {
        0
    } else {
        phase + 1
    }
}

fn ticks(period_s: f64, base_dt_s: f64) -> Result<u32, ConfigError> {
    let n = libm::round(period_s / base_dt_s);
    if !(1.0..=2_147_483_648.0).contains(&n) {
        return Err(ConfigError::Schedule);
    }
    Ok(n as u32)
}

impl Controller {
    /// Design the configured controller (f64; slow, call at start-up or after a
    /// parameter change, not per tick).
    pub fn new(cfg: &ControllerConfig) -> Result<Self, ConfigError> {
        if !(cfg.base_dt_s.is_finite() && cfg.base_dt_s > 0.0) {
            return Err(ConfigError::Schedule);
        }
        let plausible = cfg.xo_plausible_m.is_finite() && cfg.xo_plausible_m > 0.0;
        if !(cfg.limits.is_valid() && plausible) {
            return Err(ConfigError::Limits);
        }
        let mut n_h = 1;
        let (law, n_c) = match cfg.kind {
            ControllerKind::MpcEso => {
                let gains =
                    MpcGains::design(&cfg.plant, cfg.mpc_eso).map_err(ConfigError::Design)?;
                let eso_gains = EsoFixedGains::new(&cfg.eso).map_err(ConfigError::Eso)?;
                if !cfg.td.is_valid() {
                    return Err(ConfigError::Td);
                }
                n_h = ticks(cfg.eso.h_s, cfg.base_dt_s)?;
                let td_params = TdParams {
                    h_s: cfg.eso.h_s as f32,
                    ..cfg.td
                };
                let law = Law::MpcEso {
                    gains,
                    eso_gains,
                    b0: cfg.eso.b0 as f32,
                    mpc: Mpc::new(0.0),
                    eso: EsoFixed::default(),
                    td: Td::default(),
                    td_params,
                };
                (law, ticks(cfg.mpc_eso.ts_s, cfg.base_dt_s)?)
            }
            ControllerKind::CmpcEso => {
                let gains = CmpcGains::design(&cfg.plant, cfg.cmpc, &cfg.limits, cfg.base_dt_s)
                    .map_err(ConfigError::Design)?;
                let eso_gains = EsoFixedGains::new(&cfg.eso).map_err(ConfigError::Eso)?;
                n_h = ticks(cfg.eso.h_s, cfg.base_dt_s)?;
                let law = Law::CmpcEso {
                    gains,
                    eso_gains,
                    b0: cfg.eso.b0 as f32,
                    cmpc: Cmpc::new(0.0),
                    eso: EsoFixed::default(),
                };
                (law, ticks(cfg.cmpc.ts_s, cfg.base_dt_s)?)
            }
            ControllerKind::Mpc => {
                let gains = MpcGains::design(&cfg.plant, cfg.mpc).map_err(ConfigError::Design)?;
                let law = Law::Mpc {
                    gains,
                    mpc: Mpc::new(0.0),
                };
                (law, ticks(cfg.mpc.ts_s, cfg.base_dt_s)?)
            }
            ControllerKind::Pid => {
                if !cfg.pid.is_valid() {
                    return Err(ConfigError::Pid);
                }
                let law = Law::Pid {
                    params: cfg.pid,
                    pid: Pid::new(0.0),
                };
                (law, ticks(cfg.pid.ts_s as f64, cfg.base_dt_s)?)
            }
            ControllerKind::FuzzyPid => {
                if !cfg.fuzzy.is_valid() {
                    return Err(ConfigError::Pid);
                }
                let law = Law::Fuzzy {
                    params: cfg.fuzzy,
                    fuzzy: FuzzyPid::new(0.0),
                };
                (law, ticks(cfg.fuzzy.base.ts_s as f64, cfg.base_dt_s)?)
            }
        };
        Ok(Self {
            kind: cfg.kind,
            law,
            limits: cfg.limits,
            xo_plausible_m: cfg.xo_plausible_m,
            n_h,
            n_c,
            k: 0,
            phase_h: 0,
            phase_c: 0,
            v_cmd_mps: 0.0,
            saturated: false,
            started: false,
        })
    }

    /// The law this controller runs.
    pub fn kind(&self) -> ControllerKind {
        self.kind
    }

    /// Base ticks per ESO/TD update and per MPC/PID update.
    pub fn periods(&self) -> (u32, u32) {
        (self.n_h, self.n_c)
    }

    /// Base ticks done so far.
    pub fn tick_count(&self) -> u64 {
        self.k
    }

    /// The command in force, m/s.
    pub fn command(&self) -> f32 {
        self.v_cmd_mps
    }

    /// The ESO state `[z1 m, z2 m/s, z3 m/s^2]` (MPC-ESO only).
    pub fn eso_estimates(&self) -> Option<[f32; 3]> {
        self.eso_state().map(|e| e.to_f32())
    }

    /// The raw fixed-point ESO state (MPC-ESO and constrained MPC-ESO only).
    pub fn eso_state(&self) -> Option<EsoFixed> {
        match &self.law {
            Law::MpcEso { eso, .. } | Law::CmpcEso { eso, .. } => Some(*eso),
            _ => None,
        }
    }

    /// The TD output `[v1 m, v2 m/s]` (MPC-ESO only).
    pub fn td_output(&self) -> Option<[f32; 2]> {
        match &self.law {
            Law::MpcEso { td, .. } => Some([td.v1_m, td.v2_mps]),
            _ => None,
        }
    }

    /// The share of `cmpc-eso`'s acceleration limit in force: 1 until its
    /// moves ring, lower after ([`crate::cmpc`], `Cmpc::watch_ringing`);
    /// `None` for the other laws.
    pub fn acceleration_share(&self) -> Option<f32> {
        match &self.law {
            Law::CmpcEso { cmpc, .. } => Some(cmpc.a_scale),
            _ => None,
        }
    }

    /// The commanded power-piston position u, m.
    pub fn position_command(&self) -> f32 {
        match &self.law {
            Law::MpcEso { mpc, .. } | Law::Mpc { mpc, .. } => mpc.u_m,
            Law::Pid { pid, .. } => pid.u_m,
            Law::Fuzzy { fuzzy, .. } => fuzzy.pid.u_m,
            Law::CmpcEso { cmpc, .. } => cmpc.u_m,
        }
    }

    /// Stop: the command becomes 0 until the next controller update.
    pub fn hold(&mut self) {
        self.v_cmd_mps = 0.0;
        if let Law::CmpcEso { cmpc, .. } = &mut self.law {
            // Its command is rebuilt every base tick from the program's move.
            cmpc.v_mpc_mps = 0.0;
        }
    }

    fn bumpless_start(&mut self, xo_m: f32, xi_m: f32) {
        let u0 = clamp(xi_m, self.limits.x_min_m, self.limits.x_max_m);
        match &mut self.law {
            Law::MpcEso { mpc, eso, td, .. } => {
                mpc.u_m = u0;
                // Pos::saturating_from_num (xo_m is finite).
                eso.z1 = Pos::from_bits(fxp::f32_to_q::<{ POS_FRAC as i32 }>(xo_m));
                td.v1_m = xo_m;
            }
            Law::Mpc { mpc, .. } => mpc.u_m = u0,
            Law::Pid { pid, .. } => pid.u_m = u0,
            Law::Fuzzy { fuzzy, .. } => fuzzy.pid.u_m = u0,
            Law::CmpcEso { cmpc, eso, .. } => {
                cmpc.u_m = u0;
                eso.z1 = Pos::from_bits(fxp::f32_to_q::<{ POS_FRAC as i32 }>(xo_m));
            }
        }
    }

    /// One base tick: the measurement at t_k and the reference r(t_k) in, the
    /// drive command to hold over the next base period out.
    ///
    /// Never panics. A NaN or infinite Xo or reference gives the command 0 and
    /// [`Flags::NON_FINITE_INPUT`], and leaves the law's state untouched.
    pub fn step(&mut self, sample: &Sample, ref_m: f32) -> Output {
        // k mod n_h == 0 and k mod n_c == 0, from the phase counters.
        let eso_tick = self.phase_h == 0;
        let ctl_tick = self.phase_c == 0;
        self.k = self.k.wrapping_add(1);
        self.phase_h = next_phase(self.phase_h, self.n_h, self.k);
        self.phase_c = next_phase(self.phase_c, self.n_c, self.k);
        let mut flags = 0u8;
        if !(sample.xo_m.is_finite() && ref_m.is_finite()) {
            self.v_cmd_mps = 0.0;
            return Output {
                v_cmd_mps: 0.0,
                flags: Flags(Flags::NON_FINITE_INPUT),
            };
        }
        let lim = self.limits;
        let y = clamp(sample.xo_m, -self.xo_plausible_m, self.xo_plausible_m);
        if y != sample.xo_m {
            flags |= Flags::OUT_OF_RANGE;
        }
        let r = clamp(ref_m, lim.x_min_m, lim.x_max_m);
        if r != ref_m {
            flags |= Flags::REF_CLAMPED;
        }
        if !self.started {
            let xi = if sample.xi_m.is_finite() {
                sample.xi_m
            } else {
                0.0
            };
            self.bumpless_start(y, xi);
            self.started = true;
        }
        self.law_tick(sample, lim, y, r, (eso_tick, ctl_tick));
        if self.saturated {
            flags |= Flags::SATURATED;
        }
        if !self.v_cmd_mps.is_finite() {
            self.v_cmd_mps = 0.0;
            flags |= Flags::NON_FINITE_OUTPUT;
        }
        let v = clamp(self.v_cmd_mps, -lim.v_max_mps, lim.v_max_mps);
        Output {
            v_cmd_mps: v,
            flags: Flags(flags),
        }
    }

    /// The selected law's part of [`Self::step`] at the checked measurement
    /// `y` and reference `r`: sets `v_cmd_mps` and `saturated`. Always
    /// inlined: the board's tick stays one function.
    #[inline(always)]
    fn law_tick(&mut self, sample: &Sample, lim: Limits, y: f32, r: f32, ticks: (bool, bool)) {
        let (eso_tick, ctl_tick) = ticks;
        match &mut self.law {
            Law::MpcEso {
                gains,
                eso_gains,
                b0,
                mpc,
                eso,
                td,
                td_params,
            } => {
                if eso_tick {
                    td.update(td_params, r);
                }
                if ctl_tick {
                    let z = eso.to_f32();
                    let r_td = clamp(td.v1_m, lim.x_min_m, lim.x_max_m);
                    let obs = Observed {
                        z2_mps: z[1],
                        z3_mps2: z[2],
                        b0_v_mps2: *b0 * self.v_cmd_mps,
                    };
                    let out = mpc.tick(gains, &lim, y, r_td, Some(obs));
                    self.v_cmd_mps = out.v_cmd_mps;
                    self.saturated = out.saturated;
                }
                if eso_tick {
                    // Pos/Vel::saturating_from_num, without the generic conversion.
                    let u = Vel::from_bits(fxp::f32_to_q::<{ VEL_FRAC as i32 }>(self.v_cmd_mps));
                    let y = Pos::from_bits(fxp::f32_to_q::<{ POS_FRAC as i32 }>(y));
                    eso.update(eso_gains, y, u);
                }
            }
            Law::Mpc { gains, mpc } => {
                if ctl_tick {
                    let out = mpc.tick(gains, &lim, y, r, None);
                    self.v_cmd_mps = out.v_cmd_mps;
                    self.saturated = out.saturated;
                }
            }
            Law::Pid { params, pid } => {
                if ctl_tick {
                    let out = pid.tick(params, &lim, y, r);
                    self.v_cmd_mps = out.v_cmd_mps;
                    self.saturated = out.saturated;
                }
            }
            Law::Fuzzy { params, fuzzy } => {
                if ctl_tick {
                    let out = fuzzy.tick(params, &lim, y, r);
                    self.v_cmd_mps = out.v_cmd_mps;
                    self.saturated = out.saturated;
                }
            }
            Law::CmpcEso {
                gains,
                eso_gains,
                b0,
                cmpc,
                eso,
            } => {
                // Every base tick: the compliance feedforward on top of the
                // program's move (crate::cmpc, "The compliance feedforward").
                let v_ff = cmpc.compliance_ff(gains, &lim, sample.ft_n);
                if ctl_tick {
                    let z = eso.to_f32();
                    let input = CmpcInput {
                        y_m: y,
                        r_m: r,
                        ft_n: sample.ft_n,
                        xi_m: sample.xi_m,
                        observed: Observed {
                            z2_mps: z[1],
                            z3_mps2: z[2],
                            b0_v_mps2: *b0 * self.v_cmd_mps,
                        },
                    };
                    self.saturated = cmpc.tick(gains, &lim, &input).saturated;
                }
                self.v_cmd_mps = cmpc.v_mpc_mps + v_ff;
                if eso_tick {
                    let u = Vel::from_bits(fxp::f32_to_q::<{ VEL_FRAC as i32 }>(self.v_cmd_mps));
                    let y = Pos::from_bits(fxp::f32_to_q::<{ POS_FRAC as i32 }>(y));
                    eso.update(eso_gains, y, u);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phase_counters_are_k_mod_n_including_the_wrap_of_k() {
        let cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
        let mut c = Controller::new(&cfg).unwrap();
        let (n_h, n_c) = c.periods();
        assert_eq!((n_h, n_c), (60, 1000));
        let sample = Sample::default();
        // Ordinary ticks, then the last ticks before k wraps around (u64::MAX is
        // not a multiple of 60 or 1000, so the phases jump back to 0 at the wrap).
        for start in [0u64, 123_456_789, u64::MAX - 2_500] {
            c.k = start;
            c.phase_h = (start % n_h as u64) as u32;
            c.phase_c = (start % n_c as u64) as u32;
            for _ in 0..5_000 {
                let k = c.k;
                assert_eq!(c.phase_h as u64, k % n_h as u64, "k = {k}");
                assert_eq!(c.phase_c as u64, k % n_c as u64, "k = {k}");
                c.step(&sample, 0.01);
            }
        }
        assert!(c.k < 3_000, "k wrapped");
        // A non-finite input still advances the schedule.
        let k = c.k;
        c.step(&sample, f32::NAN);
        assert_eq!(c.k, k + 1);
        assert_eq!(c.phase_h as u64, c.k % n_h as u64);
    }
}

//! A rig of this family: the nominal plant of plant.md section 4 with the
//! plant-side effects of [`Effect`] hooked into its right-hand side, and the
//! classical RK4 of section 4.2 over the extended state.

use super::effects::Effect;
use super::plant::ix::*;
use super::plant::{Params, N_STATES};

/// The extended state (the 11 nominal states first, see [`super::plant::ix`],
/// then the fifth family's, see [`fx`]).
pub type State = [f64; fx::NX];

/// Indices of the states the fifth family's effects add after
/// [`super::plant::ix::NX`] (effects on one part of the rig share a block).
pub mod fx {
    use super::super::plant::ix;
    /// Slip of a friction-locked joint ([`super::Effect::BacklashLockedPlay`]), m.
    pub const SLIP: usize = ix::NX;
    /// Drive state: the motor force ([`super::Effect::MotorBackEmf`]), N.
    pub const DRV: usize = ix::NX + 1;
    /// Bubble temperature ([`super::Effect::AirBubbleThermal`]), K.
    pub const TB: usize = ix::NX + 2;
    /// Actuating chamber pressure behind a slug ([`super::Effect::AirSlug`]), Pa.
    pub const P1B: usize = ix::NX + 3;
    /// Flow of hose 1's oil column towards the actuating cylinder, m^3/s.
    pub const QH: usize = ix::NX + 4;
    /// Load fixture position ([`super::Effect::LoadFixture`]), m.
    pub const XF: usize = ix::NX + 5;
    /// Its speed, m/s.
    pub const VF: usize = ix::NX + 6;
    /// Length of each hose's wall block.
    pub const HW_LEN: usize = 18;
    /// Hose 1's wall block: the five creep volumes (m^3) and the braid's
    /// play state (Pa) of [`super::Effect::HoseCreepBraid`], or the 18 relay
    /// states of [`super::Effect::HosePreisach`].
    pub const HW1: usize = ix::NX + 7;
    /// Hose 2's wall block.
    pub const HW2: usize = HW1 + HW_LEN;
    /// Length of the state vector.
    pub const NX: usize = HW2 + HW_LEN;
}

/// Time constants of [`Effect::HoseCreepBraid`]'s creep spectrum, s.
pub const CREEP_TAU: [f64; 5] = [0.004, 0.02, 0.1, 0.5, 2.5];
/// Adiabatic index of the air of [`Effect::AirBubbleThermal`].
const GAMMA_AIR: f64 = 1.4;

/// Universal gas constant, J/(mol K).
pub const R_GAS: f64 = 8.314_462_618;
/// Ambient (and initial gas) temperature, K.
pub const T_AMB: f64 = 293.15;

/// The effects of one rig, sorted by the part of the rig they act on (at
/// most one per part).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Parts {
    coupling: Option<Effect>,
    drive: Option<Effect>,
    friction: Option<Effect>,
    leak: Option<Effect>,
    air: Option<Effect>,
    hose: Option<Effect>,
    acc: Option<Effect>,
    lvdt_filter: Option<Effect>,
    membrane: Option<Effect>,
    spring: Option<Effect>,
    relief: Option<Effect>,
    rupture: Option<Effect>,
    lead: Option<Effect>,
    fixture: Option<Effect>,
}

/// A simulated rig: parameters, effects and the integrator.
#[derive(Clone, Debug, PartialEq)]
pub struct Rig {
    /// The rig's parameters (nominal unless a [`Effect::ParamScale`] applies).
    pub p: Params,
    /// Every effect of the rig, plant- and sensor-side.
    pub effects: Vec<Effect>,
    parts: Parts,
    /// Power piston position (XP) at rest with no load, m.
    xp_offset: f64,
    /// Accumulator gas, mol.
    gas_mol: f64,
    /// Molar heat capacity at constant volume, J/(mol K).
    cv: f64,
    /// Weights of [`Effect::HoseCreepBraid`]'s creep spectrum (sum 1).
    creep_w: [f64; 5],
    /// [`Effect::HosePreisach`]'s relays: up and down thresholds (Pa) and
    /// volume (m^3).
    relays: [[f64; 3]; fx::HW_LEN],
    /// Gas of [`Effect::AirBubbleThermal`], mol.
    bubble_mol: f64,
}

fn put(slot: &mut Option<Effect>, e: Effect) {
    assert!(slot.is_none(), "two effects on one part of the rig: {e:?}");
    *slot = Some(e);
}

impl Rig {
    /// The nominal rig.
    pub fn nominal() -> Self {
        Self::new(&[])
    }

    /// A rig with these effects (at most one per part of the rig).
    pub fn new(effects: &[Effect]) -> Self {
        let mut p = Params::NOMINAL;
        let mut parts = Parts::default();
        for &e in effects {
            match e {
                Effect::ParamScale {
                    m,
                    beta_e,
                    hose_c,
                    tau_m,
                    v_gas0,
                    c_visc,
                } => {
                    p.m *= m;
                    p.beta_e *= beta_e;
                    p.ce0 *= hose_c;
                    p.cf0 *= hose_c;
                    p.cs0 *= hose_c;
                    p.tau_m *= tau_m;
                    p.v_gas0 *= v_gas0;
                    p.c_visc *= c_visc;
                }
                Effect::BacklashPlay { .. } | Effect::BacklashHysteresisCoupling { .. } => {
                    put(&mut parts.coupling, e)
                }
                Effect::DriveCurrentLimit { .. } | Effect::DriveSlewVoltage { .. } => {
                    put(&mut parts.drive, e)
                }
                Effect::FrictionLuGre { .. } | Effect::FrictionKarnopp { .. } => {
                    put(&mut parts.friction, e)
                }
                Effect::LeakOrifice { .. } | Effect::LeakDilatingGap { .. } => {
                    put(&mut parts.leak, e)
                }
                Effect::AirDissolving { .. } | Effect::AirPocket { .. } => put(&mut parts.air, e),
                Effect::HoseBoucWen { .. } | Effect::HoseStops { .. } => put(&mut parts.hose, e),
                Effect::AccumulatorWall { .. } | Effect::AccumulatorConvection { .. } => {
                    put(&mut parts.acc, e)
                }
                Effect::LvdtFilterDelay { .. } => put(&mut parts.lvdt_filter, e),
                Effect::PressureMembrane { .. } => put(&mut parts.membrane, e),
                Effect::CentringSpring { .. } => put(&mut parts.spring, e),
                Effect::ReliefToTank { .. } => put(&mut parts.relief, e),
                Effect::HoseRupture { .. } => put(&mut parts.rupture, e),
                Effect::LvdtNonlinear { .. }
                | Effect::P1Saturating { .. }
                | Effect::LvdtDrift { .. } => {}
                Effect::ParamScaleHydraulic {
                    p_acc0,
                    g_acc,
                    aa,
                    l,
                } => {
                    p.p_acc0 *= p_acc0;
                    p.g_acc *= g_acc;
                    p.aa1 *= aa;
                    p.aa2 *= aa;
                    p.l *= l;
                }
                Effect::MotorRipple { .. }
                | Effect::MotorDeadband { .. }
                | Effect::MotorBackEmf { .. } => put(&mut parts.drive, e),
                Effect::HoseCreepBraid { .. } | Effect::HosePreisach { .. } => {
                    put(&mut parts.hose, e)
                }
                Effect::BacklashWornNut { .. } | Effect::BacklashLockedPlay { .. } => {
                    put(&mut parts.coupling, e)
                }
                Effect::AirBubbleThermal { .. } | Effect::AirSlug { .. } => put(&mut parts.air, e),
                Effect::LeakScoredBore { .. } => put(&mut parts.leak, e),
                Effect::FrictionSideLoad { .. } => put(&mut parts.friction, e),
                Effect::AccumulatorForcedConvection { .. } => put(&mut parts.acc, e),
                Effect::ScrewLeadError { .. } => put(&mut parts.lead, e),
                Effect::LoadFixture { .. } => put(&mut parts.fixture, e),
                Effect::LvdtSampleHold { .. }
                | Effect::LoadCellError { .. }
                | Effect::StickyLvdtCore { .. }
                | Effect::MainsHum { .. } => {}
            }
        }
        assert!(
            parts.lead.is_none() || parts.coupling.is_none(),
            "a lead error and a coupling on one rig"
        );
        let mut creep_w = [0.0; 5];
        let mut relays = [[0.0; 3]; fx::HW_LEN];
        match parts.hose {
            Some(Effect::HoseCreepBraid { alpha, .. }) => {
                for (w, tau) in creep_w.iter_mut().zip(CREEP_TAU) {
                    *w = tau.powf(alpha);
                }
                let sum: f64 = creep_w.iter().sum();
                for w in &mut creep_w {
                    *w /= sum;
                }
            }
            Some(Effect::HosePreisach {
                v_tot,
                p_lo,
                p_hi,
                h_mean,
                ..
            }) => {
                let widths = [0.4, 1.0, 1.6];
                let shares = [0.5, 0.33, 0.17];
                for i in 0..6 {
                    let centre = p_lo + i as f64 * (p_hi - p_lo) / 5.0;
                    for j in 0..3 {
                        let h = widths[j] * h_mean;
                        relays[3 * i + j] = [centre + h, centre - h, v_tot * shares[j] / 6.0];
                    }
                }
            }
            _ => {}
        }
        let bubble_mol = match parts.air {
            Some(Effect::AirBubbleThermal {
                v_ref, p_ref_abs, ..
            }) => p_ref_abs * v_ref / (R_GAS * T_AMB),
            _ => 0.0,
        };
        let pabs0 = p.p_acc0 + p.p_atm;
        let mut gas_mol = pabs0 * p.v_gas0 / (R_GAS * T_AMB);
        if let Some(Effect::AccumulatorConvection { a_vdw, b_vdw, .. }) = parts.acc {
            // (P + a n^2/V^2)(V - n b) = n R T, by fixed-point iteration.
            for _ in 0..100 {
                let v = p.v_gas0;
                gas_mol = (pabs0 + a_vdw * gas_mol * gas_mol / (v * v)) * (v - gas_mol * b_vdw)
                    / (R_GAS * T_AMB);
            }
        }
        let mut rig = Self {
            p,
            effects: effects.to_vec(),
            parts,
            xp_offset: 0.0,
            gas_mol,
            cv: R_GAS / (p.n_poly - 1.0),
            creep_w,
            relays,
            bubble_mol,
        };
        rig.xp_offset = rig.rest(0.0)[XP];
        rig
    }

    /// True when the power piston sits behind a coupling with its own state.
    pub fn has_coupling(&self) -> bool {
        self.parts.coupling.is_some()
    }

    fn spring_force(&self, xo: f64) -> f64 {
        match self.parts.spring {
            Some(Effect::CentringSpring { k, x0 }) => -k * (xo - x0),
            _ => 0.0,
        }
    }

    /// Free air at equilibrium with absolute pressure `pabs` (form A), m^3.
    fn air_eq(a_tot: f64, henry: f64, pabs: f64) -> f64 {
        (a_tot - henry * pabs).max(0.0)
    }

    /// Rest state with load `ft0` (plant.md section 4.1, extended by the
    /// effects' own equilibria).
    pub fn rest(&self, ft0: f64) -> State {
        let p = &self.p;
        let mut x = [0.0; fx::NX];
        x[P2] = p.p_acc0;
        x[P1] = (p.aa2 * x[P2] + ft0 - self.spring_force(0.0)) / p.aa1;
        x[VF1] = p.cf0 * p.l_of(x[P1]);
        x[VS1] = p.cs0 * p.l_of(x[P1]);
        x[VF2] = p.cf0 * p.l_of(x[P2]);
        x[VS2] = p.cs0 * p.l_of(x[P2]);
        x[VG] = p.v_gas0;
        let f_hyd0 = p.power_piston_force(x[P1], x[P2]);
        match self.parts.coupling {
            Some(Effect::BacklashPlay {
                half_play,
                k_contact,
                ..
            }) => {
                x[XP] = half_play.copysign(f_hyd0) + f_hyd0 / k_contact;
            }
            Some(Effect::BacklashHysteresisCoupling { k_lin, .. }) => x[XP] = f_hyd0 / k_lin,
            Some(Effect::BacklashWornNut { .. }) => {
                // The static contact force falls monotonically with d: bisect
                // for the d at which it balances the hydraulic force.
                let (mut lo, mut hi) = (-0.01, 0.01);
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if self.worn_nut_force(0.0, mid, 0.0) + f_hyd0 > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                x[XP] = 0.5 * (lo + hi);
            }
            Some(Effect::BacklashLockedPlay {
                half_play,
                f_lock,
                k_joint,
                k_end,
                ..
            }) => {
                // Assembled centred (slip 0); a force beyond the clamping
                // friction has thrown the flange to an end of its play.
                if f_hyd0.abs() <= f_lock {
                    x[XP] = f_hyd0 / k_joint;
                } else {
                    let del = (half_play + (f_hyd0.abs() - f_lock) / k_end).copysign(f_hyd0);
                    x[XP] = del;
                    x[fx::SLIP] = del - f_lock.copysign(f_hyd0) / k_joint;
                }
            }
            _ => {}
        }
        if let Some(Effect::AirDissolving { a_tot, henry, .. }) = self.parts.air {
            x[NA1] = Self::air_eq(a_tot, henry, x[P1] + p.p_atm);
            x[NA2] = Self::air_eq(a_tot, henry, x[P2] + p.p_atm);
        }
        x[TG] = T_AMB;
        x[TW] = T_AMB;
        if self.parts.drive.is_some() {
            x[IDRV] = -f_hyd0;
        }
        x[PM1] = x[P1];
        x[PM2] = x[P2];
        if let Some(Effect::MotorBackEmf { .. }) = self.parts.drive {
            x[fx::DRV] = -f_hyd0;
        }
        match self.parts.air {
            Some(Effect::AirBubbleThermal { .. }) => x[fx::TB] = T_AMB,
            Some(Effect::AirSlug { .. }) => x[fx::P1B] = x[P1],
            _ => {}
        }
        if let Some(Effect::LoadFixture { k_f, .. }) = self.parts.fixture {
            x[fx::XF] = -ft0 / k_f;
        }
        for (hw, pj) in [(fx::HW1, x[P1]), (fx::HW2, x[P2])] {
            match self.parts.hose {
                Some(Effect::HoseCreepBraid {
                    c_creep, r0, mu, ..
                }) => {
                    for k in 0..5 {
                        x[hw + k] = c_creep * self.creep_w[k] * p.l_of(pj);
                    }
                    // Pressurised from zero: on the rising edge of the play.
                    x[hw + 5] = pj - (r0 + mu * pj.max(0.0));
                }
                Some(Effect::HosePreisach { delta, .. }) => {
                    for (k, r) in self.relays.iter().enumerate() {
                        x[hw + k] = ((pj - r[0]) / delta).clamp(0.0, 1.0);
                    }
                }
                _ => {}
            }
        }
        x
    }

    /// Static contact force of [`Effect::BacklashWornNut`] on the power
    /// piston at encoder position `xi`, nut deflection `del` and its rate.
    fn worn_nut_force(&self, xi: f64, del: f64, ddel: f64) -> f64 {
        let Some(Effect::BacklashWornNut {
            k_half,
            g_pre,
            g_wear,
            x_wear,
            w_wear,
            c_contact,
            ..
        }) = self.parts.coupling
        else {
            return 0.0;
        };
        let u = (xi - x_wear) / w_wear;
        let half_gap = 0.5 * (g_wear * (-u * u).exp() - g_pre);
        let mut f = 0.0;
        if del > half_gap {
            f += (-(k_half * (del - half_gap) + c_contact * ddel)).min(0.0);
        }
        if del < -half_gap {
            f += (-(k_half * (del + half_gap) + c_contact * ddel)).max(0.0);
        }
        f
    }

    /// Power piston position and speed for the encoder's (Xi, vi): the
    /// identity unless a [`Effect::ScrewLeadError`] applies.
    fn lead_map(&self, xi: f64, vi: f64) -> (f64, f64) {
        match self.parts.lead {
            Some(Effect::ScrewLeadError {
                lead_err,
                wobble,
                lead,
            }) => {
                let k = 2.0 * std::f64::consts::PI / lead;
                (
                    xi * (1.0 + lead_err) + wobble * (k * xi).sin(),
                    vi * (1.0 + lead_err + wobble * k * (k * xi).cos()),
                )
            }
            _ => (xi, vi),
        }
    }

    /// Line-1 pressure on the actuating piston (behind a slug: its own).
    fn p1_at_piston(&self, x: &State) -> f64 {
        match self.parts.air {
            Some(Effect::AirSlug { .. }) => x[fx::P1B],
            _ => x[P1],
        }
    }

    /// The load on the rod (positive against extension), N: the scenario's
    /// load, or the clevis force of a [`Effect::LoadFixture`] (whose
    /// derivatives go into `d`).
    fn load_on_rod(&self, x: &State, ft: f64, d: &mut State) -> f64 {
        match self.parts.fixture {
            Some(Effect::LoadFixture { m_f, k_f, c_f }) => {
                let f_clevis = k_f * (x[fx::XF] - x[XO]) + c_f * (x[fx::VF] - x[VO]);
                d[fx::XF] = x[fx::VF];
                d[fx::VF] = (-ft - f_clevis) / m_f;
                -f_clevis
            }
            _ => ft,
        }
    }

    /// Absolute accumulator gas pressure, Pa.
    pub fn gas_pabs(&self, x: &State) -> f64 {
        let p = &self.p;
        let vg = x[VG];
        match self.parts.acc {
            Some(Effect::AccumulatorWall { .. })
            | Some(Effect::AccumulatorForcedConvection { .. }) => self.gas_mol * R_GAS * x[TG] / vg,
            Some(Effect::AccumulatorConvection { a_vdw, b_vdw, .. }) => {
                let n = self.gas_mol;
                n * R_GAS * x[TG] / (vg - n * b_vdw) - a_vdw * n * n / (vg * vg)
            }
            _ => (p.p_acc0 + p.p_atm) * (p.v_gas0 / vg).powf(p.n_poly),
        }
    }

    /// Right-hand side at time `t` with the inputs held (plant.md section 4,
    /// plus the effects).
    pub fn rhs(&self, t: f64, x: &State, v_cmd: f64, ft: f64) -> State {
        let p = &self.p;
        let mut d = [0.0; fx::NX];
        let (p1, p2) = (x[P1], x[P2]);
        let vc = v_cmd.clamp(-p.v_max, p.v_max);
        let f_hyd = p.power_piston_force(p1, p2);
        let (xp, vp, f_screw) = self.power_piston(x, f_hyd, &mut d);
        self.servo(x, vc, f_screw, &mut d);
        self.actuating_piston(x, ft, &mut d);
        let qa = self.accumulator(x, &mut d);
        let (q1, q2) = self.line_flows(t, x, vp, qa);
        // Hose relaxation (nominal).
        d[VF1] = (p.cf0 * p.l_of(p1) - x[VF1]) / p.tau_f;
        d[VS1] = (p.cs0 * p.l_of(p1) - x[VS1]) / p.tau_s;
        d[VF2] = (p.cf0 * p.l_of(p2) - x[VF2]) / p.tau_f;
        d[VS2] = (p.cs0 * p.l_of(p2) - x[VS2]) / p.tau_s;
        self.pressures(x, [q1, q2], xp, &mut d);
        self.sensor_dynamics(x, &mut d);
        d
    }

    /// The power piston, directly on the screw or behind a coupling: its
    /// position and speed for the line volumes and the force on the screw;
    /// the coupling's derivatives into `d`.
    fn power_piston(&self, x: &State, f_hyd: f64, d: &mut State) -> (f64, f64, f64) {
        let (xi, vi) = self.lead_map(x[XI], x[VI]);
        let (mut xp, mut vp, mut f_screw) = (xi, vi, f_hyd);
        if let Some(c) = self.parts.coupling {
            let del = x[XP] - xi;
            let ddel = x[VP] - vi;
            let (f_c, m_piston, c_piston) = match c {
                Effect::BacklashPlay {
                    half_play,
                    k_contact,
                    c_contact,
                    m_piston,
                    c_piston,
                } => {
                    let f = if del > half_play {
                        (-(k_contact * (del - half_play) + c_contact * ddel)).min(0.0)
                    } else if del < -half_play {
                        (-(k_contact * (del + half_play) + c_contact * ddel)).max(0.0)
                    } else {
                        0.0
                    };
                    (f, m_piston, c_piston)
                }
                Effect::BacklashHysteresisCoupling {
                    k_lin,
                    sigma,
                    f_dahl,
                    c_coupling,
                    m_piston,
                    c_piston,
                } => {
                    let z = x[ZC];
                    d[ZC] = sigma * (1.0 - z / f_dahl * ddel.signum()) * ddel;
                    (-(k_lin * del + z + c_coupling * ddel), m_piston, c_piston)
                }
                Effect::BacklashWornNut {
                    m_piston, c_piston, ..
                } => (self.worn_nut_force(xi, del, ddel), m_piston, c_piston),
                Effect::BacklashLockedPlay {
                    half_play,
                    f_lock,
                    k_joint,
                    k_end,
                    c_joint,
                    m_piston,
                    c_piston,
                } => {
                    let f_j = k_joint * (del - x[fx::SLIP]);
                    if (f_j >= f_lock && ddel > 0.0) || (f_j <= -f_lock && ddel < 0.0) {
                        d[fx::SLIP] = ddel;
                    }
                    let mut f = -(f_j + c_joint * ddel);
                    if del > half_play {
                        f -= k_end * (del - half_play);
                    }
                    if del < -half_play {
                        f -= k_end * (del + half_play);
                    }
                    (f, m_piston, c_piston)
                }
                _ => unreachable!(),
            };
            d[XP] = x[VP];
            d[VP] = (f_c + f_hyd - c_piston * x[VP]) / m_piston;
            xp = x[XP] - self.xp_offset;
            vp = x[VP];
            f_screw = -f_c;
        }
        (xp, vp, f_screw)
    }

    /// The servo drive's derivatives into `d`.
    fn servo(&self, x: &State, vc: f64, f_screw: f64, d: &mut State) {
        let p = &self.p;
        let vi = x[VI];
        d[XI] = vi;
        d[VI] = (vc - vi) / p.tau_m;
        match self.parts.drive {
            Some(Effect::DriveCurrentLimit {
                m_eq,
                f_max,
                kv,
                ki,
                c_screw,
            }) => {
                let vref = x[VREF];
                let dvref = (vc - vref) / p.tau_m;
                let f_cmd = m_eq * dvref + kv * (vref - vi) + x[IDRV];
                let f_m = f_cmd.clamp(-f_max, f_max);
                d[VREF] = dvref;
                d[IDRV] = ki * (vref - vi);
                d[VI] = (f_m + f_screw - c_screw * vi) / m_eq;
            }
            Some(Effect::DriveSlewVoltage { a_max, f_stall }) => {
                let motoring = if vc == 0.0 {
                    0.0
                } else {
                    (-f_screw * vc.signum()).max(0.0)
                };
                let v_top = p.v_max * (1.0 - motoring / f_stall).max(0.1);
                let vce = vc.clamp(-v_top, v_top);
                d[VI] = ((vce - vi) / p.tau_m).clamp(-a_max, a_max);
            }
            Some(Effect::MotorRipple {
                m_eq,
                k_v,
                v_ref,
                pitch,
            }) => {
                let f_m = m_eq * (vc - vi) / p.tau_m - f_screw;
                let u = vi.abs() / v_ref;
                let phase = 2.0 * std::f64::consts::PI * x[XI] / pitch;
                let dip = -f_m * k_v * u / (1.0 + u) * 0.5 * phase.cos();
                d[VI] = (vc - vi) / p.tau_m + dip / m_eq;
            }
            Some(Effect::MotorDeadband { v_db, q }) => {
                let over = (vc.abs() - v_db).max(0.0);
                let ve = ((over / q).round() * q).copysign(vc);
                d[VI] = (ve - vi) / p.tau_m;
            }
            Some(Effect::MotorBackEmf {
                m_eq,
                f_stall,
                v_noload,
                tau_e,
                w_c,
                f_max,
            }) => {
                let f = x[fx::DRV];
                let f_dem = (m_eq * (vc - vi) / p.tau_m - f_screw).clamp(-f_max, f_max);
                let emf = f_stall * vi / v_noload;
                let u = ((f + emf + tau_e * w_c * (f_dem - f)) / f_stall).clamp(-1.0, 1.0);
                d[fx::DRV] = (f_stall * u - f - emf) / tau_e;
                d[VI] = (f + f_screw) / m_eq;
            }
            _ => {}
        }
    }

    /// The actuating piston's derivatives (end stops, load, friction) into `d`.
    fn actuating_piston(&self, x: &State, ft: f64, d: &mut State) {
        let p = &self.p;
        let (xo, vo, p1, p2) = (x[XO], x[VO], self.p1_at_piston(x), x[P2]);
        let ft = self.load_on_rod(x, ft, d);
        let mut fs = 0.0;
        if xo > p.x_max {
            fs = -p.k_stop * (xo - p.x_max) - if vo > 0.0 { p.c_stop * vo } else { 0.0 };
        }
        if xo < p.x_min {
            fs = -p.k_stop * (xo - p.x_min) - if vo < 0.0 { p.c_stop * vo } else { 0.0 };
        }
        let f_app = p.aa1 * p1 - p.aa2 * p2 - ft - p.c_visc * vo + fs + self.spring_force(xo);
        let f_fr = match self.parts.friction {
            Some(Effect::FrictionLuGre {
                fc0,
                kp,
                ratio_s,
                vs,
                sigma0,
                sigma1,
            }) => {
                let fc = fc0 + kp * (p1.max(0.0) + p2.max(0.0));
                let g = fc + (ratio_s - 1.0) * fc * (-(vo / vs) * (vo / vs)).exp();
                let z = x[ZF];
                let dz = vo - sigma0 * vo.abs() * z / g;
                d[ZF] = dz;
                -(sigma0 * z + sigma1 * dz)
            }
            Some(Effect::FrictionKarnopp {
                f_stat,
                fc_ext,
                fc_ret,
                v_eps,
                c_stick,
            }) => {
                if vo.abs() < v_eps {
                    if f_app.abs() <= f_stat {
                        -f_app - c_stick * vo
                    } else {
                        -f_stat.copysign(f_app)
                    }
                } else if vo > 0.0 {
                    -fc_ext
                } else {
                    fc_ret
                }
            }
            Some(Effect::FrictionSideLoad {
                mu,
                n0,
                ecc,
                span0,
                v_s,
            }) => {
                let f_ax = p.aa1 * p1 - p.aa2 * p2;
                let span = (span0 - xo).max(0.2 * span0);
                let n = n0 + 2.0 * f_ax.abs() * ecc / span;
                -mu * n * vo / (vo * vo + v_s * v_s).sqrt()
            }
            _ => 0.0,
        };
        d[XO] = vo;
        d[VO] = (f_app + f_fr) / p.m;
    }

    /// The accumulator's derivatives into `d`; its flow into line 2, m^3/s.
    fn accumulator(&self, x: &State, d: &mut State) -> f64 {
        let p = &self.p;
        let p2 = x[P2];
        let vg = x[VG];
        let pg_abs = self.gas_pabs(x);
        let qa = p.g_acc * (pg_abs - p.p_atm - p2);
        d[VG] = qa;
        let cg = self.gas_mol * self.cv;
        match self.parts.acc {
            Some(Effect::AccumulatorWall {
                tau_gw,
                wall_ratio,
                tau_wa,
            }) => {
                let (tg, tw) = (x[TG], x[TW]);
                let h = cg / tau_gw;
                let cw = wall_ratio * cg;
                d[TG] = (-pg_abs * qa + h * (tw - tg)) / cg;
                d[TW] = (h * (tg - tw) + cw / tau_wa * (T_AMB - tw)) / cw;
            }
            Some(Effect::AccumulatorConvection { k_nc, b_vdw, .. }) => {
                let n = self.gas_mol;
                let tg = x[TG];
                let dt = T_AMB - tg;
                let heat = k_nc * dt.abs().cbrt() * dt;
                d[TG] = (-(n * R_GAS * tg / (vg - n * b_vdw)) * qa + heat) / cg;
            }
            Some(Effect::AccumulatorForcedConvection { tau_still, q_ref }) => {
                let h = cg / tau_still * (1.0 + qa.abs() / q_ref);
                d[TG] = (-pg_abs * qa + h * (T_AMB - x[TG])) / cg;
            }
            _ => {}
        }
        qa
    }

    /// The net flows into lines 1 and 2 from the pistons, the accumulator,
    /// the leakage and the effects outside the vocabulary, m^3/s.
    fn line_flows(&self, t: f64, x: &State, vp: f64, qa: f64) -> (f64, f64) {
        let p = &self.p;
        let (vo, p1, p2) = (x[VO], x[P1], x[P2]);
        let mut q1 = p.ap1 * vp - p.aa1 * vo;
        let mut q2 = p.aa2 * vo - p.ap2 * vp + qa;
        let dp12 = p1 - p2;
        let q12 = match self.parts.leak {
            Some(Effect::LeakOrifice { k, v_open, p_lam }) => {
                k * (1.0 + vo.abs() / v_open) * dp12 / (dp12.abs() + p_lam).sqrt()
            }
            Some(Effect::LeakDilatingGap { g0, p_dil }) => {
                g0 * dp12 * (1.0 + dp12.abs() / p_dil).powi(3)
            }
            Some(Effect::LeakScoredBore {
                g_max,
                x_a,
                x_b,
                edge,
            }) => {
                let ramp =
                    |u: f64| 0.5 * (1.0 + (0.5 * std::f64::consts::PI * u.clamp(-1.0, 1.0)).sin());
                let xo = x[XO];
                g_max * ramp((xo - x_a) / edge) * ramp((x_b - xo) / edge) * dp12
            }
            _ => 0.0,
        };
        q1 -= q12;
        q2 += q12;
        if let Some(Effect::ReliefToTank { p_crack, g }) = self.parts.relief {
            q1 -= g * (p1 - p_crack).max(0.0);
        }
        if let Some(Effect::HoseRupture { t0, g_rate }) = self.parts.rupture {
            q2 -= g_rate * (t - t0).max(0.0) * p2.max(0.0);
        }
        (q1, q2)
    }

    /// Pressures: continuity of each line, with the effects' extra
    /// compliances and flows; the derivatives into `d` (the hose
    /// relaxation's already there).
    fn pressures(&self, x: &State, q: [f64; 2], xp: f64, d: &mut State) {
        let p = &self.p;
        let (xo, q1, q2) = (x[XO], q[0], q[1]);
        let (mut q1, mut v1) = (q1 - d[VF1] - d[VS1], p.v1(xp, xo));
        if let Some(Effect::AirSlug { .. }) = self.parts.air {
            // The actuating chamber is on the slug's side of the oil column.
            q1 += p.aa1 * x[VO] - x[fx::QH];
            v1 -= p.v_dead + p.aa1 * (xo - p.x_min);
        }
        let lines = [
            (P1, q1, v1, NA1, BW1, ST1, fx::HW1),
            (
                P2,
                q2 - d[VF2] - d[VS2],
                p.v2(xp, xo),
                NA2,
                BW2,
                ST2,
                fx::HW2,
            ),
        ];
        for (j, (ip, q, v, ina, ibw, ist, ihw)) in lines.into_iter().enumerate() {
            let pj = x[ip];
            let pabs = (pj + p.p_atm).max(0.05 * p.p_atm);
            let mut num = q;
            let mut den = v / p.beta_e + p.ce0 * p.f(pj);
            if let Some(Effect::HoseCreepBraid { c_creep, .. }) = self.parts.hose {
                for k in 0..5 {
                    let dv = (c_creep * self.creep_w[k] * p.l_of(pj) - x[ihw + k]) / CREEP_TAU[k];
                    d[ihw + k] = dv;
                    num -= dv;
                }
            }
            match self.parts.air {
                Some(Effect::AirDissolving {
                    a_tot,
                    henry,
                    tau_release,
                    tau_dissolve,
                }) => {
                    let n = x[ina];
                    let neq = Self::air_eq(a_tot, henry, pabs);
                    let tau = if neq > n { tau_release } else { tau_dissolve };
                    let dn = (neq - n) / tau;
                    d[ina] = dn;
                    num += p.p_atm / pabs * dn;
                    den += n * p.p_atm / (pabs * pabs);
                }
                Some(Effect::AirPocket {
                    vb_ref,
                    p_ref_abs,
                    kappa,
                }) if j == 0 => {
                    let vb = vb_ref * (p_ref_abs / pabs).powf(1.0 / kappa);
                    den += vb / (kappa * pabs);
                }
                Some(Effect::AirBubbleThermal { tau_th, .. }) if j == 0 => {
                    let tb = x[fx::TB];
                    let vb = self.bubble_mol * R_GAS * tb / pabs;
                    den += vb / (GAMMA_AIR * pabs);
                    num += vb / GAMMA_AIR * (T_AMB - tb) / (tb * tau_th);
                }
                _ => {}
            }
            let up = num >= 0.0;
            match self.parts.hose {
                Some(Effect::HoseBoucWen {
                    c_h,
                    beta,
                    gamma,
                    n,
                    ..
                }) => {
                    let z = x[ibw];
                    let s = if up == (z >= 0.0) { 1.0 } else { -1.0 };
                    let fac = (1.0 - z.abs().powf(n) * (beta * s + gamma)).max(0.0);
                    den += c_h * fac;
                }
                Some(Effect::HoseStops { r, c }) => {
                    for i in 0..5 {
                        let s = x[ist + i];
                        if (up && s < r[i]) || (!up && s > -r[i]) {
                            den += c[i];
                        }
                    }
                }
                Some(Effect::HoseCreepBraid {
                    c_braid, r0, mu, ..
                }) => {
                    if let Some(slope) = braid_slope(up, pj, x[ihw + 5], r0, mu) {
                        den += c_braid * slope;
                    }
                }
                Some(Effect::HosePreisach { delta, .. }) => {
                    for (k, rl) in self.relays.iter().enumerate() {
                        if relay_switching(up, x[ihw + k], pj, rl, delta) {
                            den += rl[2] / delta;
                        }
                    }
                }
                _ => {}
            }
            let dp = num / den;
            d[ip] = dp;
            if let Some(Effect::AirBubbleThermal { tau_th, .. }) = self.parts.air {
                if j == 0 {
                    let tb = x[fx::TB];
                    d[fx::TB] = (T_AMB - tb) / (GAMMA_AIR * tau_th)
                        + tb * (GAMMA_AIR - 1.0) / GAMMA_AIR * dp / pabs;
                }
            }
            match self.parts.hose {
                Some(Effect::HoseBoucWen {
                    p_z,
                    beta,
                    gamma,
                    n,
                    ..
                }) => {
                    let z = x[ibw];
                    let s = if up == (z >= 0.0) { 1.0 } else { -1.0 };
                    let fac = (1.0 - z.abs().powf(n) * (beta * s + gamma)).max(0.0);
                    d[ibw] = dp / p_z * fac;
                }
                Some(Effect::HoseStops { r, .. }) => {
                    for i in 0..5 {
                        let s = x[ist + i];
                        if (up && s < r[i]) || (!up && s > -r[i]) {
                            d[ist + i] = dp;
                        }
                    }
                }
                Some(Effect::HoseCreepBraid { r0, mu, .. }) => {
                    if let Some(slope) = braid_slope(up, pj, x[ihw + 5], r0, mu) {
                        d[ihw + 5] = slope * dp;
                    }
                }
                Some(Effect::HosePreisach { delta, .. }) => {
                    for (k, rl) in self.relays.iter().enumerate() {
                        if relay_switching(up, x[ihw + k], pj, rl, delta) {
                            d[ihw + k] = dp / delta;
                        }
                    }
                }
                _ => {}
            }
        }
        if let Some(Effect::AirSlug {
            v_slug,
            p_ref_abs,
            kappa,
            inertance,
            resistance,
        }) = self.parts.air
        {
            let pb = x[fx::P1B];
            let pabs = (pb + p.p_atm).max(0.05 * p.p_atm);
            let vs = v_slug * (p_ref_abs / pabs).powf(1.0 / kappa);
            let v_oil = p.v_dead + p.aa1 * (xo - p.x_min);
            d[fx::P1B] = (x[fx::QH] - p.aa1 * x[VO]) / (v_oil / p.beta_e + vs / (kappa * pabs));
            d[fx::QH] = (x[P1] - pb - resistance * x[fx::QH]) / inertance;
        }
    }

    /// Sensor dynamics driven by the plant, into `d`.
    fn sensor_dynamics(&self, x: &State, d: &mut State) {
        let (xo, p1, p2) = (x[XO], x[P1], x[P2]);
        if let Some(Effect::LvdtFilterDelay { f_c_hz, .. }) = self.parts.lvdt_filter {
            let w = 2.0 * std::f64::consts::PI * f_c_hz;
            d[LV1] = x[LV2];
            d[LV2] = w * w * (xo - x[LV1]) - std::f64::consts::SQRT_2 * w * x[LV2];
        }
        if let Some(Effect::PressureMembrane { f_n_hz, zeta }) = self.parts.membrane {
            let w = 2.0 * std::f64::consts::PI * f_n_hz;
            for (im, imd, pj) in [(PM1, PM1D, p1), (PM2, PM2D, p2)] {
                d[im] = x[imd];
                d[imd] = w * w * (pj - x[im]) - 2.0 * zeta * w * x[imd];
            }
        }
    }

    /// One RK4 step of `p.dt` from `x` at time `t` with the inputs held, after
    /// the ball-screw software limit of plant.md section 4.2.
    pub fn step(&self, t: f64, x: &State, v_cmd: f64, ft: f64) -> State {
        let p = &self.p;
        let h = p.dt;
        let v = if (x[XI] >= p.x_max && v_cmd > 0.0) || (x[XI] <= p.x_min && v_cmd < 0.0) {
            0.0
        } else {
            v_cmd
        };
        let add = |a: &State, k: &State, s: f64| {
            let mut o = *a;
            for i in 0..fx::NX {
                o[i] += s * k[i];
            }
            o
        };
        let k1 = self.rhs(t, x, v, ft);
        let k2 = self.rhs(t, &add(x, &k1, h / 2.0), v, ft);
        let k3 = self.rhs(t, &add(x, &k2, h / 2.0), v, ft);
        let k4 = self.rhs(t, &add(x, &k3, h), v, ft);
        let mut o = *x;
        for i in 0..fx::NX {
            o[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        // Rate-independent elements stay inside their yield sets.
        if let Some(Effect::HoseStops { r, .. }) = self.parts.hose {
            for i in 0..5 {
                o[ST1 + i] = o[ST1 + i].clamp(-r[i], r[i]);
                o[ST2 + i] = o[ST2 + i].clamp(-r[i], r[i]);
            }
        }
        if let Some(Effect::HoseBoucWen { .. }) = self.parts.hose {
            o[BW1] = o[BW1].clamp(-1.0, 1.0);
            o[BW2] = o[BW2].clamp(-1.0, 1.0);
        }
        if let Some(Effect::BacklashHysteresisCoupling { f_dahl, .. }) = self.parts.coupling {
            o[ZC] = o[ZC].clamp(-f_dahl, f_dahl);
        }
        o[NA1] = o[NA1].max(0.0);
        o[NA2] = o[NA2].max(0.0);
        for (ip, hw) in [(P1, fx::HW1), (P2, fx::HW2)] {
            let pj = o[ip];
            match self.parts.hose {
                Some(Effect::HoseCreepBraid { r0, mu, .. }) => {
                    let r = r0 + mu * pj.max(0.0);
                    o[hw + 5] = o[hw + 5].clamp(pj - r, pj + r);
                }
                Some(Effect::HosePreisach { delta, .. }) => {
                    for (k, rl) in self.relays.iter().enumerate() {
                        let (u, dn) = relay_bounds(pj, rl, delta);
                        o[hw + k] = o[hw + k].clamp(u, dn);
                    }
                }
                _ => {}
            }
        }
        if let Some(Effect::BacklashLockedPlay {
            f_lock, k_joint, ..
        }) = self.parts.coupling
        {
            let del = o[XP] - o[XI];
            let e = f_lock / k_joint;
            o[fx::SLIP] = o[fx::SLIP].clamp(del - e, del + e);
        }
        o
    }

    /// The nominal part of a state (plant.md section 2).
    pub fn nominal_part(x: &State) -> [f64; N_STATES] {
        let mut o = [0.0; N_STATES];
        o.copy_from_slice(&x[..N_STATES]);
        o
    }

    /// An extended state whose nominal part is `x` and whose effect states
    /// are those of this rig at rest.
    pub fn extend(&self, x: &[f64; N_STATES]) -> State {
        let mut o = self.rest(0.0);
        o[..N_STATES].copy_from_slice(x);
        o
    }
}

/// The braid play of [`Effect::HoseCreepBraid`]: dy/dP while the braid slips
/// with the pressure moving up (`up`) or down, `None` while it holds.
fn braid_slope(up: bool, pj: f64, y: f64, r0: f64, mu: f64) -> Option<f64> {
    let mu_e = if pj > 0.0 { mu } else { 0.0 };
    let r = r0 + mu * pj.max(0.0);
    // 1 Pa of tolerance: the state sits on the edge after each step's clamp.
    if up && pj - y >= r - 1.0 {
        Some(1.0 - mu_e)
    } else if !up && pj - y <= -r + 1.0 {
        Some(1.0 + mu_e)
    } else {
        None
    }
}

/// Bounds (lower, upper) of a Preisach relay's state at pressure `pj`
/// (relay: up threshold, down threshold, volume).
fn relay_bounds(pj: f64, rl: &[f64; 3], delta: f64) -> (f64, f64) {
    (
        ((pj - rl[0]) / delta).clamp(0.0, 1.0),
        ((pj - rl[1]) / delta + 1.0).clamp(0.0, 1.0),
    )
}

/// True while a Preisach relay in state `s` switches with the pressure
/// moving up (`up`) or down.
fn relay_switching(up: bool, s: f64, pj: f64, rl: &[f64; 3], delta: f64) -> bool {
    let (u, dn) = relay_bounds(pj, rl, delta);
    if up {
        pj > rl[0] && pj < rl[0] + delta && s <= u + 1e-12
    } else {
        pj < rl[1] && pj > rl[1] - delta && s >= dn - 1e-12
    }
}

//! The nominal 11-state plant of docs/model.md sections 2-4.
//!
//! [`Plant::derivative`] is the right-hand side of section 4, evaluated in the order
//! written there; [`Plant::step`] is the classical RK4 step of section 4.2 with the
//! ball-screw software limit applied first. The physical parameters come from
//! [`dca_core::params::PlantParams`], so the controller design and the simulator always
//! agree on the numbers.
//!
//! The right-hand side is split into small helpers ([`Plant::forces_n`],
//! [`Plant::flows`], [`Plant::pressure_rates`]) so that extra effects (leakage,
//! friction, ...) can later be composed around them without touching the nominal
//! equations. Constants that do not depend on the state are computed once in
//! [`Plant::new`].
//!
//! The GRNN hose variants ([`HoseModel::Grnn`], [`HoseModel::GrnnMemory`]) make the
//! pressure equation implicit in dP/dt; it is solved per line and per RK stage by
//! safeguarded Newton ([`crate::model::hose::grnn::GrnnHose::solve_dp_paps`]), warm-started
//! at the line's previous solution (the memory hose: moved by a predicted step for the
//! change of the line's flow and volume). That solver state lives in the plant behind
//! relaxed atomics, so `derivative` and `step` keep `&self` and `Plant` stays
//! `Send + Sync`; [`Plant::initial_state`] resets it, which keeps runs reproducible.
//! The memory variant's filter states are ordinary plant states (the hose-volume
//! slots). Run the GRNN variants at dt = 2e-4 s (docs/model.md section 4).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use dca_core::params::PlantParams;

use crate::model::hose::grnn::{GrnnHose, GrnnHoseKind};
use crate::model::hose::local::{LocalCache, LocalStats};

/// Number of plant states (docs/model.md section 2).
pub const N_STATES: usize = 11;

/// Nominal integration step of docs/model.md section 3.1 / 4.2, s.
pub const NOMINAL_DT_S: f64 = 1.0e-4;

/// Plant state of docs/model.md section 2, SI units.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct State {
    /// Power (master) piston position Xi, m.
    pub xi_m: f64,
    /// Power piston velocity vi (servo speed-loop state), m/s.
    pub vi_mps: f64,
    /// Actuating (slave) piston position Xo, m.
    pub xo_m: f64,
    /// Actuating piston velocity vo, m/s.
    pub vo_mps: f64,
    /// Line-1 pressure P1 (gauge), Pa.
    pub p1_pa: f64,
    /// Line-2 pressure P2 (gauge), Pa.
    pub p2_pa: f64,
    /// Hose-1 fast relaxation volume Vf1, m^3 (hose model
    /// [`HoseModel::GrnnMemory`]: the first filtered line-1 pressure, Pa).
    pub vf1_m3: f64,
    /// Hose-1 slow creep volume Vs1, m^3 ([`HoseModel::GrnnMemory`]: the second
    /// filtered line-1 pressure, Pa).
    pub vs1_m3: f64,
    /// Hose-2 fast relaxation volume Vf2, m^3 ([`HoseModel::GrnnMemory`]: the
    /// first filtered line-2 pressure, Pa).
    pub vf2_m3: f64,
    /// Hose-2 slow creep volume Vs2, m^3 ([`HoseModel::GrnnMemory`]: the second
    /// filtered line-2 pressure, Pa).
    pub vs2_m3: f64,
    /// Accumulator gas volume Vg, m^3.
    pub vg_m3: f64,
}

impl State {
    /// Index of Xi in [`State::as_array`].
    pub const XI: usize = 0;
    /// Index of vi in [`State::as_array`].
    pub const VI: usize = 1;
    /// Index of Xo in [`State::as_array`].
    pub const XO: usize = 2;
    /// Index of vo in [`State::as_array`].
    pub const VO: usize = 3;
    /// Index of P1 in [`State::as_array`].
    pub const P1: usize = 4;
    /// Index of P2 in [`State::as_array`].
    pub const P2: usize = 5;
    /// Index of Vf1 in [`State::as_array`].
    pub const VF1: usize = 6;
    /// Index of Vs1 in [`State::as_array`].
    pub const VS1: usize = 7;
    /// Index of Vf2 in [`State::as_array`].
    pub const VF2: usize = 8;
    /// Index of Vs2 in [`State::as_array`].
    pub const VS2: usize = 9;
    /// Index of Vg in [`State::as_array`].
    pub const VG: usize = 10;

    /// The state as an array in the order of docs/model.md section 2 (see the index constants).
    #[inline]
    pub fn as_array(&self) -> [f64; N_STATES] {
        [
            self.xi_m,
            self.vi_mps,
            self.xo_m,
            self.vo_mps,
            self.p1_pa,
            self.p2_pa,
            self.vf1_m3,
            self.vs1_m3,
            self.vf2_m3,
            self.vs2_m3,
            self.vg_m3,
        ]
    }

    /// The state from an array in the order of docs/model.md section 2.
    #[inline]
    pub fn from_array(a: [f64; N_STATES]) -> Self {
        Self {
            xi_m: a[Self::XI],
            vi_mps: a[Self::VI],
            xo_m: a[Self::XO],
            vo_mps: a[Self::VO],
            p1_pa: a[Self::P1],
            p2_pa: a[Self::P2],
            vf1_m3: a[Self::VF1],
            vs1_m3: a[Self::VS1],
            vf2_m3: a[Self::VF2],
            vs2_m3: a[Self::VS2],
            vg_m3: a[Self::VG],
        }
    }

    /// True if every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.as_array().iter().all(|v| v.is_finite())
    }
}

impl From<[f64; N_STATES]> for State {
    fn from(a: [f64; N_STATES]) -> Self {
        Self::from_array(a)
    }
}

impl From<State> for [f64; N_STATES] {
    fn from(s: State) -> Self {
        s.as_array()
    }
}

/// Hose wall model of both lines (docs/model.md section 4, "Variants").
///
/// The two GRNN variants name the *kind* of hose; the fitted network itself lives
/// in the [`Plant`] (shared through an `Arc`): [`Plant::new`] uses the shipped
/// default networks ([`GrnnHose::shipped_static`], [`GrnnHose::shipped_memory`]),
/// [`Plant::with_grnn_hose`] any other. This keeps `HoseModel` a `Copy` name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum HoseModel {
    /// The nominal pressure-stiffening viscoelastic hose (`hose_model = "nonlinear"`).
    #[default]
    Nonlinear,
    /// Same equations with f(P) replaced by f(P_lin) and L(P) by f(P_lin) P, where
    /// P_lin = [`PlantParams::p_nom_pa`] (1 MPa nominally, the paper's eq. 1-4 with
    /// constant coefficients).
    Linear,
    /// Rigid hose: dVf = dVs = 0 and dP = Q beta_e / V (oil compressibility only).
    Rigid,
    /// The paper's GRNN hose (`grnn`): wall rate g(P, dP/dt) from a static GRNN, the
    /// pressure equation implicit in dP/dt and solved per line and per RK stage by
    /// safeguarded Newton ([`GrnnHose::solve_dp_paps`]). The hose volume states are
    /// unused (held at 0). Run it at dt = 2e-4 s (docs/model.md section 4).
    Grnn,
    /// GRNN hose with memory (`grnn-memory`): g(P, dP/dt, P - P_f1, P - P_f2) with
    /// P_fk = lowpass(P, tau_k) (see [`crate::model::hose::memory`]). The filter states are
    /// plant states: the slots `vf*` hold P_f1 and `vs*` hold P_f2 (Pa), with
    /// dP_fk/dt = (P - P_fk) / tau_k. Same implicit solve as [`HoseModel::Grnn`].
    GrnnMemory,
}

impl HoseModel {
    /// Every hose model, in documentation order.
    pub const ALL: [Self; 5] = [
        Self::Nonlinear,
        Self::Linear,
        Self::Rigid,
        Self::Grnn,
        Self::GrnnMemory,
    ];

    /// The command-line / configuration name (`nonlinear`, `linear`, `rigid`,
    /// `grnn`, `grnn-memory`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Nonlinear => "nonlinear",
            Self::Linear => "linear",
            Self::Rigid => "rigid",
            Self::Grnn => "grnn",
            Self::GrnnMemory => "grnn-memory",
        }
    }

    /// The hose model with the given name, `None` if unknown.
    pub fn by_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }

    /// True for the GRNN variants (implicit pressure equation).
    pub fn is_grnn(self) -> bool {
        matches!(self, Self::Grnn | Self::GrnnMemory)
    }
}

/// The GRNN hose of a plant and its solver state: the last Newton solution of
/// each line (the warm start) and iteration counters.
///
/// The warm start is interior-mutable so that [`Plant::derivative`] and
/// [`Plant::step`] keep `&self` for every hose model. It is held in relaxed
/// atomics (not a `Cell`), so a `Plant` stays `Sync` and can be shared by
/// threads; each clone has its own copy. It only chooses where Newton starts:
/// results differ by about the hose's Newton tolerance
/// ([`GrnnHose::newton_tol_paps`]) with another start. Runs are bit-reproducible because [`Plant::initial_state`]
/// resets it (as every run starts there), provided one plant instance is not
/// stepped by two threads at once (give each thread its own clone).
///
/// A memory hose also keeps one [`LocalCache`] per line (its evaluator's local
/// sample list and, with [`GrnnHose::taylor_steps`], the last exact evaluation
/// from which later ones may be Taylor steps, within the evaluator's
/// bound). [`Plant::initial_state`] drops that anchor and resets the counters
/// (the list is kept: the values do not depend on it); a clone carries a copy
/// of the caches, so it continues exactly as the original would.
struct GrnnLines {
    hose: Arc<GrnnHose>,
    /// Last solution per line, f64 bits.
    warm: [AtomicU64; 2],
    /// Per line, f64 bits: the last solve's inflow Q (m^3/s), coefficient a
    /// (m^3/Pa) and residual slope (m^3/Pa; NaN before the first solve), for
    /// the warm-start predictor ([`GrnnHose::predicts_warm_start`]).
    last_q: [AtomicU64; 2],
    last_a: [AtomicU64; 2],
    last_fp: [AtomicU64; 2],
    /// Evaluation cache per line.
    cache: [Mutex<LocalCache>; 2],
    /// Solves and iterations since the last reset.
    solves: AtomicU64,
    iterations: AtomicU64,
}

impl GrnnLines {
    fn new(hose: Arc<GrnnHose>) -> Self {
        let cache = || {
            Mutex::new(if hose.taylor_steps() {
                LocalCache::with_taylor()
            } else {
                LocalCache::new()
            })
        };
        Self {
            cache: [cache(), cache()],
            hose,
            warm: [AtomicU64::new(0), AtomicU64::new(0)],
            last_q: [AtomicU64::new(0), AtomicU64::new(0)],
            last_a: [AtomicU64::new(0), AtomicU64::new(0)],
            last_fp: [
                AtomicU64::new(f64::NAN.to_bits()),
                AtomicU64::new(f64::NAN.to_bits()),
            ],
            solves: AtomicU64::new(0),
            iterations: AtomicU64::new(0),
        }
    }

    fn reset(&self) {
        for w in &self.warm {
            w.store(0f64.to_bits(), Ordering::Relaxed);
        }
        for f in &self.last_fp {
            f.store(f64::NAN.to_bits(), Ordering::Relaxed);
        }
        self.solves.store(0, Ordering::Relaxed);
        self.iterations.store(0, Ordering::Relaxed);
        for c in &self.cache {
            let mut c = c.lock().unwrap_or_else(|e| e.into_inner());
            c.reset_stats();
            c.forget();
        }
    }
}

impl GrnnLines {
    /// Where the next solve of `line` starts: its last solution, or (hose with
    /// [`GrnnHose::predicts_warm_start`]) that solution moved by one Newton step
    /// for the change of the inflow Q and of the coefficient a since the last
    /// solve, the wall rate's change with P and the filters neglected:
    ///
    /// dP_0 = dP_last + ((Q - Q_last) - (a - a_last) dP_last) / (a + f'_last - a_last),
    ///
    /// f'_last the last residual slope. It only chooses where Newton starts.
    #[inline]
    fn warm_start_paps(&self, line: usize, q_m3ps: f64, a_m3ppa: f64) -> f64 {
        let warm = f64::from_bits(self.warm[line].load(Ordering::Relaxed));
        if !self.hose.predicts_warm_start() {
            return warm;
        }
        let fp = f64::from_bits(self.last_fp[line].load(Ordering::Relaxed));
        let q0 = f64::from_bits(self.last_q[line].load(Ordering::Relaxed));
        let a0 = f64::from_bits(self.last_a[line].load(Ordering::Relaxed));
        let den = a_m3ppa + fp - a0;
        let next = warm + ((q_m3ps - q0) - (a_m3ppa - a0) * warm) / den;
        if fp.is_finite() && den > 0.0 && next.is_finite() {
            next
        } else {
            warm
        }
    }
}

impl Clone for GrnnLines {
    fn clone(&self) -> Self {
        let c = Self::new(self.hose.clone());
        for (d, s) in [
            (&c.warm, &self.warm),
            (&c.last_q, &self.last_q),
            (&c.last_a, &self.last_a),
            (&c.last_fp, &self.last_fp),
        ] {
            for (d, s) in d.iter().zip(s) {
                d.store(s.load(Ordering::Relaxed), Ordering::Relaxed);
            }
        }
        for (d, s) in c.cache.iter().zip(&self.cache) {
            let mut d = d.lock().unwrap_or_else(|e| e.into_inner());
            *d = s.lock().unwrap_or_else(|e| e.into_inner()).clone();
            d.reset_stats();
        }
        c
    }
}

impl PartialEq for GrnnLines {
    /// Equal if the networks are (the solver state is not compared).
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.hose, &other.hose) || *self.hose == *other.hose
    }
}

impl std::fmt::Debug for GrnnLines {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GrnnLines")
            .field("kind", &self.hose.kind())
            .field("description", &self.hose.description())
            .field("sigma", &self.hose.sigma())
            .field("n_samples", &self.hose.n_samples())
            .finish_non_exhaustive()
    }
}

/// Volume flows of docs/model.md section 4, m^3/s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Flows {
    /// Oil displaced into line 1, Q1 = AP1 vi - AA1 vo, m^3/s.
    pub q1_m3ps: f64,
    /// Net oil flow into line 2, Q2 = AA2 vo - AP2 vi + Qa, m^3/s.
    pub q2_m3ps: f64,
    /// Flow from the accumulator into line 2, Qa = G_acc (Pacc - P2), m^3/s.
    pub qa_m3ps: f64,
}

/// Pressure and hose-volume rates of both lines (docs/model.md section 4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PressureRates {
    /// dP1/dt, Pa/s.
    pub dp1_paps: f64,
    /// dP2/dt, Pa/s.
    pub dp2_paps: f64,
    /// dVf1/dt, m^3/s.
    pub dvf1_m3ps: f64,
    /// dVs1/dt, m^3/s.
    pub dvs1_m3ps: f64,
    /// dVf2/dt, m^3/s.
    pub dvf2_m3ps: f64,
    /// dVs2/dt, m^3/s.
    pub dvs2_m3ps: f64,
}

/// Rates of one line: (dP, dVf, dVs).
#[derive(Clone, Copy)]
struct LineRates {
    dp_paps: f64,
    dvf_m3ps: f64,
    dvs_m3ps: f64,
}

/// The nominal plant: parameters, hose model and precomputed constants.
#[derive(Clone, Debug, PartialEq)]
pub struct Plant {
    params: PlantParams,
    hose_model: HoseModel,
    // Precomputed constants (all derived from `params` in `new`).
    inv_tau_m_ps: f64,
    inv_m_pkg: f64,
    inv_tau_f_ps: f64,
    inv_tau_s_ps: f64,
    inv_beta_e_ppa: f64,
    /// 2 V_dead + V_hose + V_fit, m^3 (the position-independent part of V1 and V2).
    v_fixed_m3: f64,
    /// P_acc0 + P_atm (absolute precharge state), Pa.
    p_acc0_abs_pa: f64,
    /// Linear hose only: Ce0 f(P_lin), Cf0 f(P_lin), Cs0 f(P_lin), m^3/Pa.
    ce_lin_m3pp: f64,
    cf_lin_m3pp: f64,
    cs_lin_m3pp: f64,
    /// GRNN hose models only: the network and the Newton warm start.
    grnn: Option<GrnnLines>,
    /// GRNN memory hose only: 1 / tau_k of its filters, 1/s.
    inv_tau_mem_ps: [f64; 2],
}

impl Default for Plant {
    fn default() -> Self {
        Self::nominal()
    }
}

impl Plant {
    /// A plant with the given parameters and hose model; precomputes the constants.
    /// The GRNN hose models use the shipped default networks
    /// ([`GrnnHose::shipped_static`], [`GrnnHose::shipped_memory`]; built once per
    /// process on first use).
    pub fn new(params: PlantParams, hose_model: HoseModel) -> Self {
        let hose = match hose_model {
            HoseModel::Grnn => Some(GrnnHose::shipped_static()),
            HoseModel::GrnnMemory => Some(GrnnHose::shipped_memory()),
            _ => None,
        };
        Self::build(params, hose_model, hose)
    }

    /// A plant whose hoses are the given GRNN hose (hose model [`HoseModel::Grnn`]
    /// for a static network, [`HoseModel::GrnnMemory`] for a memory network).
    pub fn with_grnn_hose(params: PlantParams, hose: Arc<GrnnHose>) -> Self {
        let model = match hose.kind() {
            GrnnHoseKind::Static => HoseModel::Grnn,
            GrnnHoseKind::Memory => HoseModel::GrnnMemory,
        };
        Self::build(params, model, Some(hose))
    }

    fn build(params: PlantParams, hose_model: HoseModel, hose: Option<Arc<GrnnHose>>) -> Self {
        let h = &params.hose;
        let f_lin = h.stiffening(params.p_nom_pa);
        let inv_tau_mem_ps = match &hose {
            Some(g) if g.kind() == GrnnHoseKind::Memory => g.taus_s().map(|t| 1.0 / t),
            _ => [0.0; 2],
        };
        Self {
            params,
            hose_model,
            inv_tau_m_ps: 1.0 / params.tau_m_s,
            inv_m_pkg: 1.0 / params.m_kg,
            inv_tau_f_ps: 1.0 / h.tau_f_s,
            inv_tau_s_ps: 1.0 / h.tau_s_s,
            inv_beta_e_ppa: 1.0 / params.beta_e_pa,
            v_fixed_m3: 2.0 * params.v_dead_m3 + params.v_hose_m3() + params.v_fit_m3,
            p_acc0_abs_pa: params.p_acc0_pa + params.p_atm_pa,
            ce_lin_m3pp: h.ce0_m3pp * f_lin,
            cf_lin_m3pp: h.cf0_m3pp * f_lin,
            cs_lin_m3pp: h.cs0_m3pp * f_lin,
            grnn: hose.map(GrnnLines::new),
            inv_tau_mem_ps,
        }
    }

    /// The GRNN hose of a GRNN hose model, `None` otherwise.
    pub fn grnn_hose(&self) -> Option<&Arc<GrnnHose>> {
        self.grnn.as_ref().map(|g| &g.hose)
    }

    /// Work of the memory hose's evaluator ([`LocalStats`], both lines) since
    /// the last [`Plant::initial_state`] (zero for a static GRNN hose; `None`
    /// for the other hose models).
    pub fn grnn_eval_stats(&self) -> Option<LocalStats> {
        self.grnn.as_ref().map(|g| {
            let mut t = LocalStats::default();
            for c in &g.cache {
                let s = c.lock().unwrap_or_else(|e| e.into_inner()).stats();
                t.evals += s.evals;
                t.kernels += s.kernels;
                t.distances += s.distances;
                t.rebuilds += s.rebuilds;
                t.taylor += s.taylor;
                t.visited += s.visited;
            }
            t
        })
    }

    /// GRNN hose models: (implicit solves, Newton iterations) since the last
    /// [`Plant::initial_state`]; `None` for the other hose models.
    pub fn grnn_solver_stats(&self) -> Option<(u64, u64)> {
        self.grnn.as_ref().map(|g| {
            (
                g.solves.load(Ordering::Relaxed),
                g.iterations.load(Ordering::Relaxed),
            )
        })
    }

    /// This plant (hose model and any GRNN hose kept) with other parameters.
    pub fn with_params(&self, params: PlantParams) -> Self {
        Self::build(params, self.hose_model, self.grnn_hose().cloned())
    }

    /// The nominal plant: [`PlantParams::NOMINAL`] with the nonlinear hose.
    pub fn nominal() -> Self {
        Self::new(PlantParams::NOMINAL, HoseModel::Nonlinear)
    }

    /// The physical parameters.
    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// The hose model.
    pub fn hose_model(&self) -> HoseModel {
        self.hose_model
    }

    /// Accumulator pressure (gauge) at gas volume `vg_m3`, Pa:
    /// Pacc = (P_acc0 + P_atm) (V_gas0 / Vg)^n_poly - P_atm.
    ///
    /// The power is evaluated as exp(n_poly ln(V_gas0 / Vg)) (libm): within about one
    /// ulp of `libm::pow` here (|ln(V_gas0 / Vg)| is a few percent), at less than half
    /// its cost (18 ns against 45 ns; it is the most expensive term of the derivative).
    #[inline]
    pub fn p_acc_pa(&self, vg_m3: f64) -> f64 {
        let p = &self.params;
        let ratio = p.v_gas0_m3 / vg_m3;
        self.p_acc0_abs_pa * libm::exp(p.n_poly * libm::log(ratio)) - p.p_atm_pa
    }

    /// Oil volumes (V1, V2) of the two lines at positions (Xi, Xo), m^3.
    #[inline]
    pub fn line_volumes(&self, xi_m: f64, xo_m: f64) -> (f64, f64) {
        let p = &self.params;
        let v1 = self.v_fixed_m3 + p.ap1_m2 * (p.x_max_m - xi_m) + p.aa1_m2 * (xo_m - p.x_min_m);
        let v2 = self.v_fixed_m3 + p.ap2_m2 * (xi_m - p.x_min_m) + p.aa2_m2 * (p.x_max_m - xo_m);
        (v1, v2)
    }

    /// Equilibrium hose volumes (Vf, Vs) at pressure `p_pa` for the active hose model:
    /// (Cf0 L(P), Cs0 L(P)) (nonlinear), (Cf0 f(P_lin) P, Cs0 f(P_lin) P) (linear),
    /// (0, 0) (rigid, grnn), m^3; (P, P) for grnn-memory, whose slots hold filtered
    /// pressures (Pa). Shared by [`Plant::initial_state`] and the rates so that the
    /// rest state is an equilibrium to the last bit.
    #[inline]
    fn hose_targets_m3(&self, p_pa: f64) -> (f64, f64) {
        let h = &self.params.hose;
        match self.hose_model {
            HoseModel::Nonlinear => {
                let l = h.log_pressure(p_pa);
                (h.cf0_m3pp * l, h.cs0_m3pp * l)
            }
            HoseModel::Linear => (self.cf_lin_m3pp * p_pa, self.cs_lin_m3pp * p_pa),
            HoseModel::Rigid | HoseModel::Grnn => (0.0, 0.0),
            HoseModel::GrnnMemory => (p_pa, p_pa),
        }
    }

    /// Rest state of docs/model.md section 4.1 for the initial load `ft0_n` (creep in
    /// equilibrium). The hose volumes are the equilibrium volumes of the active hose
    /// model (section 4.1 exactly for the nonlinear hose; f(P_lin) P in place of L(P)
    /// for the linear hose; 0 for the rigid hose, whose hose volumes never change), so
    /// the rest state is an equilibrium of every hose model except the GRNN ones
    /// (a GRNN's wall rate at dP/dt = 0 is not exactly 0). For the GRNN hose models
    /// this also resets the Newton warm start and the solver counters (see
    /// [`Plant::grnn_solver_stats`]), so that every run starting here is
    /// reproducible.
    pub fn initial_state(&self, ft0_n: f64) -> State {
        if let Some(g) = &self.grnn {
            g.reset();
        }
        let p = &self.params;
        let p2 = p.p_acc0_pa;
        let p1 = (p.aa2_m2 * p2 + ft0_n) / p.aa1_m2;
        let (vf1, vs1) = self.hose_targets_m3(p1);
        let (vf2, vs2) = self.hose_targets_m3(p2);
        State {
            xi_m: 0.0,
            vi_mps: 0.0,
            xo_m: 0.0,
            vo_mps: 0.0,
            p1_pa: p1,
            p2_pa: p2,
            vf1_m3: vf1,
            vs1_m3: vs1,
            vf2_m3: vf2,
            vs2_m3: vs2,
            vg_m3: p.v_gas0_m3,
        }
    }

    /// Ball-screw software limit of docs/model.md section 4.2: 0 if Xi >= X_max and
    /// v_cmd > 0, or Xi <= X_min and v_cmd < 0; otherwise `v_cmd_mps`, m/s.
    #[inline]
    pub fn software_limited_v_cmd(&self, xi_m: f64, v_cmd_mps: f64) -> f64 {
        let p = &self.params;
        if (xi_m >= p.x_max_m && v_cmd_mps > 0.0) || (xi_m <= p.x_min_m && v_cmd_mps < 0.0) {
            0.0
        } else {
            v_cmd_mps
        }
    }

    /// Hydraulic force on the power piston, AP1 P1 - AP2 P2 (positive
    /// opposing extension), N.
    pub fn piston_force_n(&self, p1_pa: f64, p2_pa: f64) -> f64 {
        self.params.ap1_m2 * p1_pa - self.params.ap2_m2 * p2_pa
    }

    /// Net force on the actuating piston, AA1 P1 - AA2 P2 - Ft - c_visc vo + Fs
    /// (Fs: end stops), N.
    #[inline]
    pub fn forces_n(&self, x: &State, ft_n: f64) -> f64 {
        let p = &self.params;
        let (xo, vo) = (x.xo_m, x.vo_mps);
        let fs = if xo > p.x_max_m {
            -p.k_stop_npm * (xo - p.x_max_m) - if vo > 0.0 { p.c_stop_nspm * vo } else { 0.0 }
        } else if xo < p.x_min_m {
            -p.k_stop_npm * (xo - p.x_min_m) - if vo < 0.0 { p.c_stop_nspm * vo } else { 0.0 }
        } else {
            0.0
        };
        p.aa1_m2 * x.p1_pa - p.aa2_m2 * x.p2_pa - ft_n - p.c_visc_nspm * vo + fs
    }

    /// Line flows Qa, Q1, Q2 of docs/model.md section 4.
    #[inline]
    pub fn flows(&self, x: &State) -> Flows {
        self.flows_with_qa(x, self.accumulator_flow_m3ps(x))
    }

    /// The accumulator's flow Qa into line 2 (it depends on the gas volume and
    /// P2 only), m^3/s.
    #[inline]
    pub fn accumulator_flow_m3ps(&self, x: &State) -> f64 {
        self.params.g_acc_m3pspa * (self.p_acc_pa(x.vg_m3) - x.p2_pa)
    }

    /// [`Plant::flows`] with the accumulator's flow `qa_m3ps` already known
    /// (the same numbers to the last bit when it is
    /// [`Plant::accumulator_flow_m3ps`] of `x`).
    #[inline]
    pub fn flows_with_qa(&self, x: &State, qa_m3ps: f64) -> Flows {
        let p = &self.params;
        let qa = qa_m3ps;
        let q1 = p.ap1_m2 * x.vi_mps - p.aa1_m2 * x.vo_mps;
        let q2 = p.aa2_m2 * x.vo_mps - p.ap2_m2 * x.vi_mps + qa;
        Flows {
            q1_m3ps: q1,
            q2_m3ps: q2,
            qa_m3ps: qa,
        }
    }

    /// Pressure and hose-volume rates of both lines for the given net flows into the
    /// lines (docs/model.md section 4, per the active hose model).
    #[inline]
    pub fn pressure_rates(&self, x: &State, q1_m3ps: f64, q2_m3ps: f64) -> PressureRates {
        let (v1, v2) = self.line_volumes(x.xi_m, x.xo_m);
        let l1 = self.line_rates(0, x.p1_pa, x.vf1_m3, x.vs1_m3, v1, q1_m3ps);
        let l2 = self.line_rates(1, x.p2_pa, x.vf2_m3, x.vs2_m3, v2, q2_m3ps);
        PressureRates {
            dp1_paps: l1.dp_paps,
            dp2_paps: l2.dp_paps,
            dvf1_m3ps: l1.dvf_m3ps,
            dvs1_m3ps: l1.dvs_m3ps,
            dvf2_m3ps: l2.dvf_m3ps,
            dvs2_m3ps: l2.dvs_m3ps,
        }
    }

    /// Rates of one line (`line` 0 or 1) with pressure `p`, hose volumes (`vf`, `vs`),
    /// oil volume `v` and net inflow `q`.
    #[inline]
    fn line_rates(
        &self,
        line: usize,
        p_pa: f64,
        vf_m3: f64,
        vs_m3: f64,
        v_m3: f64,
        q_m3ps: f64,
    ) -> LineRates {
        if let Some(g) = &self.grnn {
            return self.grnn_line_rates(g, line, p_pa, vf_m3, vs_m3, v_m3, q_m3ps);
        }
        let h = &self.params.hose;
        // Wall compliance of the instantaneous element, m^3/Pa.
        let ce_m3pp = match self.hose_model {
            HoseModel::Nonlinear => h.ce0_m3pp * h.stiffening(p_pa),
            HoseModel::Linear => self.ce_lin_m3pp,
            HoseModel::Rigid | HoseModel::Grnn | HoseModel::GrnnMemory => {
                return LineRates {
                    dp_paps: q_m3ps * self.params.beta_e_pa / v_m3,
                    dvf_m3ps: 0.0,
                    dvs_m3ps: 0.0,
                }
            }
        };
        let (vf_eq, vs_eq) = self.hose_targets_m3(p_pa);
        let dvf = (vf_eq - vf_m3) * self.inv_tau_f_ps;
        let dvs = (vs_eq - vs_m3) * self.inv_tau_s_ps;
        let dp = (q_m3ps - dvf - dvs) / (v_m3 * self.inv_beta_e_ppa + ce_m3pp);
        LineRates {
            dp_paps: dp,
            dvf_m3ps: dvf,
            dvs_m3ps: dvs,
        }
    }

    /// Rates of one line with a GRNN hose: the implicit pressure equation solved by
    /// [`GrnnHose::solve_dp_paps`], warm-started at the line's previous solution;
    /// for the memory hose the slots (`vf`, `vs`) are the filtered pressures (Pa).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn grnn_line_rates(
        &self,
        g: &GrnnLines,
        line: usize,
        p_pa: f64,
        vf: f64,
        vs: f64,
        v_m3: f64,
        q_m3ps: f64,
    ) -> LineRates {
        let memory = g.hose.kind() == GrnnHoseKind::Memory;
        let mem_mpa = if memory {
            [(p_pa - vf) * 1e-6, (p_pa - vs) * 1e-6]
        } else {
            [0.0; 2]
        };
        let a_m3ppa = v_m3 * self.inv_beta_e_ppa;
        let warm = g.warm_start_paps(line, q_m3ps, a_m3ppa);
        let s = g.hose.solve_dp_paps_cached(
            p_pa,
            mem_mpa,
            q_m3ps,
            a_m3ppa,
            warm,
            &mut g.cache[line].lock().unwrap_or_else(|e| e.into_inner()),
        );
        g.warm[line].store(s.dp_paps.to_bits(), Ordering::Relaxed);
        if g.hose.predicts_warm_start() {
            g.last_q[line].store(q_m3ps.to_bits(), Ordering::Relaxed);
            g.last_a[line].store(a_m3ppa.to_bits(), Ordering::Relaxed);
            g.last_fp[line].store(s.df_ddp_m3ppa.to_bits(), Ordering::Relaxed);
        }
        g.solves.fetch_add(1, Ordering::Relaxed);
        g.iterations
            .fetch_add(u64::from(s.iterations), Ordering::Relaxed);
        let (dvf, dvs) = if memory {
            (
                (p_pa - vf) * self.inv_tau_mem_ps[0],
                (p_pa - vs) * self.inv_tau_mem_ps[1],
            )
        } else {
            (0.0, 0.0)
        };
        LineRates {
            dp_paps: s.dp_paps,
            dvf_m3ps: dvf,
            dvs_m3ps: dvs,
        }
    }

    /// The servo's acceleration towards the command `vc_mps` (within
    /// +-v_max) at the speed `vi_mps`, m/s^2: first order, time constant tau_m.
    #[inline]
    pub fn servo_rate(&self, vc_mps: f64, vi_mps: f64) -> f64 {
        (vc_mps - vi_mps) * self.inv_tau_m_ps
    }

    /// Right-hand side dx/dt of docs/model.md section 4 at state `x`, servo velocity
    /// command `v_cmd_mps` (clamped to +-v_max here; the software limit is applied by
    /// [`Plant::step`], not here) and load `ft_n`. Order of the result: section 2.
    #[inline]
    pub fn derivative(&self, x: &State, v_cmd_mps: f64, ft_n: f64) -> [f64; N_STATES] {
        let p = &self.params;
        let vc = v_cmd_mps.clamp(-p.v_max_mps, p.v_max_mps);
        let d_xi = x.vi_mps;
        let d_vi = self.servo_rate(vc, x.vi_mps);
        let d_xo = x.vo_mps;
        let d_vo = self.forces_n(x, ft_n) * self.inv_m_pkg;
        let q = self.flows(x);
        let r = self.pressure_rates(x, q.q1_m3ps, q.q2_m3ps);
        [
            d_xi,
            d_vi,
            d_xo,
            d_vo,
            r.dp1_paps,
            r.dp2_paps,
            r.dvf1_m3ps,
            r.dvs1_m3ps,
            r.dvf2_m3ps,
            r.dvs2_m3ps,
            q.qa_m3ps,
        ]
    }

    /// One classical RK4 step of length `dt_s` (docs/model.md section 4.2): the software
    /// limit is applied to `v_cmd_mps` from the state at the start of the step, then
    /// `v_cmd_mps` and `ft_n` are held over all four stages.
    pub fn step(&self, x: &mut State, v_cmd_mps: f64, ft_n: f64, dt_s: f64) {
        let v = self.software_limited_v_cmd(x.xi_m, v_cmd_mps);
        let x0 = x.as_array();
        let half = 0.5 * dt_s;
        let k1 = self.derivative(x, v, ft_n);
        let k2 = self.derivative(&State::from_array(axpy(&x0, half, &k1)), v, ft_n);
        let k3 = self.derivative(&State::from_array(axpy(&x0, half, &k2)), v, ft_n);
        let k4 = self.derivative(&State::from_array(axpy(&x0, dt_s, &k3)), v, ft_n);
        let sixth = dt_s / 6.0;
        *x = State::from_array(core::array::from_fn(|i| {
            x0[i] + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        }));
    }
}

/// x + h k, entry by entry.
#[inline]
fn axpy(x: &[f64; N_STATES], h: f64, k: &[f64; N_STATES]) -> [f64; N_STATES] {
    core::array::from_fn(|i| x[i] + h * k[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// exp(n ln r) agrees with libm::pow(r, n) to a few ulp over a wide gas-volume range
    /// (0.5 ... 2 V_gas0, far beyond the +-10 % of the nominal scenarios).
    #[test]
    fn accumulator_power_matches_pow() {
        let plant = Plant::nominal();
        let p = plant.params();
        let mut worst: f64 = 0.0;
        for i in 0..=1000 {
            let vg = p.v_gas0_m3 * (0.5 + 1.5 * f64::from(i) / 1000.0);
            let abs_pa = plant.p_acc_pa(vg) + p.p_atm_pa;
            let want = plant.p_acc0_abs_pa * libm::pow(p.v_gas0_m3 / vg, p.n_poly);
            worst = worst.max(((abs_pa - want) / want).abs());
        }
        println!("exp(n ln r) vs pow: worst relative difference {worst:e}");
        assert!(
            worst <= 4.0 * f64::EPSILON,
            "worst relative difference {worst:e}"
        );
    }

    #[test]
    fn hose_model_names() {
        for m in HoseModel::ALL {
            assert_eq!(HoseModel::by_name(m.name()), Some(m));
        }
        assert_eq!(HoseModel::by_name("grnn"), Some(HoseModel::Grnn));
        assert_eq!(
            HoseModel::by_name("grnn-memory"),
            Some(HoseModel::GrnnMemory)
        );
        assert_eq!(HoseModel::by_name("GRNN"), None);
        assert_eq!(HoseModel::default(), HoseModel::Nonlinear);
    }

    #[test]
    fn rigid_hose_is_oil_only() {
        let plant = Plant::new(PlantParams::NOMINAL, HoseModel::Rigid);
        let mut x = plant.initial_state(0.0);
        x.vi_mps = 0.01;
        let dx = plant.derivative(&x, 0.0, 0.0);
        let (v1, _) = plant.line_volumes(x.xi_m, x.xo_m);
        let q1 = plant.params().ap1_m2 * 0.01;
        assert_eq!(dx[State::P1], q1 * plant.params().beta_e_pa / v1);
        assert_eq!(
            [
                dx[State::VF1],
                dx[State::VS1],
                dx[State::VF2],
                dx[State::VS2]
            ],
            [0.0; 4]
        );
    }

    /// The linear hose equals the nonlinear one at P = P_lin in its instantaneous
    /// compliance and in the equilibrium hose volumes' slope.
    #[test]
    fn linear_hose_uses_f_at_p_lin() {
        let p = PlantParams::NOMINAL;
        let lin = Plant::new(p, HoseModel::Linear);
        let f_lin = p.hose.stiffening(p.p_nom_pa);
        assert_eq!(f_lin, 0.5);
        let x = lin.initial_state(0.0);
        assert!((x.vf2_m3 - p.hose.cf0_m3pp * 0.5 * x.p2_pa).abs() <= 1e-30);
        assert!((x.vs1_m3 - p.hose.cs0_m3pp * 0.5 * x.p1_pa).abs() <= 1e-30);
    }
}

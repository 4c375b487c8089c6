//! GRNN hose wall models for the plant (docs/model.md section 4, "Variants").
//!
//! The hose wall rate g (mm^3/s) comes from a GRNN: either the paper's static
//! map g(P, dP/dt) (MPa, MPa/s) ([`GrnnHoseKind::Static`]) or the memory GRNN of
//! [`super::memory`] with two low-pass filtered pressures as extra inputs
//! ([`GrnnHoseKind::Memory`]). Because g depends on dP/dt, the continuity
//! equation of a line is implicit in dP/dt:
//!
//! (V / beta_e) dP + 1e-9 g(1e-6 P, 1e-6 dP, memory) = Q        (SI: Pa/s, m^3/s)
//!
//! [`GrnnHose::solve_dp_paps`] solves it by safeguarded Newton on dP with the
//! analytic GRNN slope: the root is bracketed by [(Q - g_max)/a, (Q - g_min)/a]
//! (a = V / beta_e, g_min/g_max the extreme training outputs, which bound every
//! GRNN output); a Newton step that leaves the current bracket, or a
//! non-positive slope, is replaced by bisection; the iteration starts at the
//! warm start (clamped into the bracket) and stops when the step is below
//! the hose's tolerance ([`NEWTON_STEP_TOL_PAPS`] = 1e-3 Pa/s static,
//! [`MEMORY_NEWTON_TOL_PAPS`] memory) or rounds to zero, after at most 30
//! iterations.
//!
//! Evaluation: the static map uses [`FastGrnn`] (table + truncated sum), the
//! memory map [`LocalGrnn`] (a cached local list of samples, one
//! [`LocalCache`] per line: [`GrnnHose::solve_dp_paps_cached`]; in the plant
//! mostly Taylor steps from the line's last exact evaluation,
//! [`GrnnHose::taylor_steps`]); both within a stated bound of the direct sum.
//! [`GrnnHose::from_memory_truncated`] keeps the memory map's former evaluator
//! ([`Truncated`], grid-binned) for comparisons.

use std::sync::{Arc, OnceLock};

use super::data::{DynamicData, QuasiStaticData};
use super::fast::{FastGrnn, Truncated};
use super::local::{LocalCache, LocalGrnn};
use super::memory::{MemoryGrnn, MEMORY_DIM, N_FILTERS};
use super::net::{FitError, Grnn};

/// The paper's spread sigma of the static hose GRNN (z-score units; docs/model.md
/// section 9).
pub const PAPER_SIGMA: f64 = 0.1;

/// Newton stops when the step is below this, Pa/s (the static hose's
/// tolerance; see [`GrnnHose::newton_tol_paps`]).
pub const NEWTON_STEP_TOL_PAPS: f64 = 1e-3;
/// The memory hose's Newton tolerance, Pa/s: the returned Newton update is then
/// within about C step^2 of the root, far below what the evaluator's own bound
/// ([`MEMORY_TRUNC_EPS`]) already moves dP/dt (measured on the plant's
/// trajectories: docs/model.md section 4, test `grnn_plant.rs`).
pub const MEMORY_NEWTON_TOL_PAPS: f64 = 100.0;
/// Newton iteration limit.
pub const NEWTON_MAX_ITER: u32 = 30;

/// Filter time constants of the shipped memory hose, s (chosen by
/// [`crate::studies::grnn::memory::select`] on all three shipped dynamic runs; a test checks
/// the choice).
pub const SHIPPED_MEMORY_TAUS_S: [f64; N_FILTERS] = [0.01, 0.3];
/// Spread of the shipped memory hose (chosen with the time constants).
pub const SHIPPED_MEMORY_SIGMA: f64 = 0.1;
/// Consecutive dynamic samples closer than this (z units) are merged into one
/// weighted sample in the shipped memory hose ([`Grnn::fit_merged`]): 28 000
/// samples become about 9 000; on a held-out run the predictions move by less
/// than 0.2 % of the output range and the scores not at all (test
/// `grnn_memory.rs`).
pub const SHIPPED_MEMORY_MERGE_Z: f64 = 0.05;
/// Relative bound of the memory hose's evaluator: |evaluated - direct sum| <=
/// MEMORY_TRUNC_EPS (Y_max - Y_min).
pub const MEMORY_TRUNC_EPS: f64 = 1e-3;

/// Which GRNN a hose uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GrnnHoseKind {
    /// Static map g(P, dP/dt) (the paper's model).
    Static,
    /// Memory GRNN g(P, dP/dt, P - lowpass(P, tau_1), P - lowpass(P, tau_2)).
    Memory,
}

#[derive(Clone, Debug, PartialEq)]
enum Evaluator {
    Table(FastGrnn),
    Trunc { trunc: Truncated, z: MemoryZ },
    Local { local: LocalGrnn, z: MemoryZ },
}

/// The memory net's input standardisation, `(x - mean) / std`, with the
/// reciprocals kept.
#[derive(Clone, Debug, PartialEq)]
struct MemoryZ {
    mean: [f64; MEMORY_DIM],
    inv_std: [f64; MEMORY_DIM],
}

impl MemoryZ {
    fn of(net: &Grnn) -> Self {
        let sc = net.scaler();
        Self {
            mean: core::array::from_fn(|k| sc.mean[k]),
            inv_std: core::array::from_fn(|k| 1.0 / sc.std[k]),
        }
    }

    /// The standardised inputs `[P, dP/dt, memory 1, memory 2]`.
    fn apply(&self, p_mpa: f64, dpdt_mpa_s: f64, mem_mpa: [f64; N_FILTERS]) -> [f64; MEMORY_DIM] {
        let x = [p_mpa, dpdt_mpa_s, mem_mpa[0], mem_mpa[1]];
        core::array::from_fn(|k| (x[k] - self.mean[k]) * self.inv_std[k])
    }
}

/// A GRNN hose wall model ready for the integrator.
#[derive(Clone, Debug, PartialEq)]
pub struct GrnnHose {
    kind: GrnnHoseKind,
    eval: Evaluator,
    taus_s: [f64; N_FILTERS],
    sigma: f64,
    n_samples: usize,
    g_min: f64,
    g_max: f64,
    bound: f64,
    newton_tol_paps: f64,
    predict_warm: bool,
    taylor_steps: bool,
    description: String,
}

/// Result of one implicit solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solve {
    /// dP/dt, Pa/s.
    pub dp_paps: f64,
    /// Newton/bisection iterations used (each one GRNN evaluation).
    pub iterations: u32,
    /// Slope of the residual at the last evaluation, a + 1e-15 dg/d(dP/dt),
    /// m^3/Pa (the plant's warm-start predictor uses it).
    pub df_ddp_m3ppa: f64,
}

impl GrnnHose {
    /// A static hose from a two-input network on (P MPa, dP/dt MPa/s) -> mm^3/s.
    pub fn from_static(net: &Grnn, description: impl Into<String>) -> Result<Self, FitError> {
        if net.dim() != 2 {
            return Err(FitError::Shape(
                "a static hose needs inputs (P, dP/dt)".into(),
            ));
        }
        let fast = FastGrnn::new(net);
        let (g_min, g_max) = net.output_range();
        Ok(Self {
            kind: GrnnHoseKind::Static,
            bound: fast.error_bound(),
            eval: Evaluator::Table(fast),
            taus_s: [0.0; N_FILTERS],
            sigma: net.sigma(),
            n_samples: net.len(),
            g_min,
            g_max,
            newton_tol_paps: NEWTON_STEP_TOL_PAPS,
            predict_warm: false,
            taylor_steps: false,
            description: description.into(),
        })
    }

    /// A memory hose from a memory GRNN, evaluated by [`LocalGrnn`] within
    /// [`MEMORY_TRUNC_EPS`] of the output range.
    pub fn from_memory(m: &MemoryGrnn, description: impl Into<String>) -> Result<Self, FitError> {
        Self::from_memory_eps(m, MEMORY_TRUNC_EPS, description)
    }

    /// A memory hose evaluated by [`LocalGrnn`] within `eps` (in (0, 1)) of the
    /// output range (a tight `eps` gives a reference close to the direct sum).
    pub fn from_memory_eps(
        m: &MemoryGrnn,
        eps: f64,
        description: impl Into<String>,
    ) -> Result<Self, FitError> {
        let mut h = Self::from_memory_truncated(m, description)?;
        let local = LocalGrnn::new(&m.net, eps);
        h.bound = local.error_bound();
        h.eval = Evaluator::Local {
            local,
            z: MemoryZ::of(&m.net),
        };
        Ok(h)
    }

    /// A memory hose with the former evaluator, [`Truncated`] (grid-binned, bound
    /// [`MEMORY_TRUNC_EPS`] of the range): the same model, tens of times slower
    /// in the closed-loop plant (`host-sim bench`); kept for side-by-side
    /// comparisons (the bench, tests).
    pub fn from_memory_truncated(
        m: &MemoryGrnn,
        description: impl Into<String>,
    ) -> Result<Self, FitError> {
        if m.net.dim() != MEMORY_DIM {
            return Err(FitError::Shape(
                "a memory hose needs the memory inputs".into(),
            ));
        }
        if m.taus_s.iter().any(|t| !(*t > 0.0 && t.is_finite())) {
            return Err(FitError::BadParameter(
                "filter time constants must be positive".into(),
            ));
        }
        let trunc = Truncated::new(&m.net, MEMORY_TRUNC_EPS);
        let (g_min, g_max) = m.net.output_range();
        Ok(Self {
            kind: GrnnHoseKind::Memory,
            bound: trunc.error_bound(),
            eval: Evaluator::Trunc {
                trunc,
                z: MemoryZ::of(&m.net),
            },
            taus_s: m.taus_s,
            sigma: m.net.sigma(),
            n_samples: m.net.len(),
            g_min,
            g_max,
            newton_tol_paps: MEMORY_NEWTON_TOL_PAPS,
            predict_warm: true,
            taylor_steps: true,
            description: description.into(),
        })
    }

    /// The plant's default static hose: the GRNN on all 2520 shipped
    /// quasi-static samples at the paper's sigma = 0.1 (docs/model.md section 9).
    /// Built once per process (about 0.4 s), then shared.
    pub fn shipped_static() -> Arc<Self> {
        static CELL: OnceLock<Arc<GrnnHose>> = OnceLock::new();
        CELL.get_or_init(|| {
            let d = QuasiStaticData::shipped();
            let (x, y) = d.xy(&(0..d.samples.len()).collect::<Vec<_>>());
            let net = Grnn::fit2(&x, &y, PAPER_SIGMA).expect("shipped data fit");
            Arc::new(
                Self::from_static(&net, "static GRNN, shipped quasi-static data, sigma 0.1")
                    .expect("two inputs"),
            )
        })
        .clone()
    }

    /// The plant's default memory hose: the memory GRNN on all three shipped
    /// dynamic runs (all samples, near-duplicates merged, see
    /// [`SHIPPED_MEMORY_MERGE_Z`]) with [`SHIPPED_MEMORY_TAUS_S`] and
    /// [`SHIPPED_MEMORY_SIGMA`]. Built once per process, then shared.
    pub fn shipped_memory() -> Arc<Self> {
        static CELL: OnceLock<Arc<GrnnHose>> = OnceLock::new();
        CELL.get_or_init(|| {
            Arc::new(
                Self::from_memory(
                    &Self::shipped_memory_grnn(),
                    "memory GRNN, shipped dynamic data",
                )
                .expect("memory inputs"),
            )
        })
        .clone()
    }

    /// The network of [`GrnnHose::shipped_memory`], fitted anew (a few tens of
    /// milliseconds in release).
    pub fn shipped_memory_grnn() -> MemoryGrnn {
        let d = DynamicData::shipped();
        let runs: Vec<_> = d.runs.iter().collect();
        MemoryGrnn::fit_merged(
            &runs,
            SHIPPED_MEMORY_TAUS_S,
            SHIPPED_MEMORY_SIGMA,
            1,
            SHIPPED_MEMORY_MERGE_Z,
        )
        .expect("shipped data fit")
    }

    /// Static or memory.
    pub fn kind(&self) -> GrnnHoseKind {
        self.kind
    }

    /// Filter time constants of a memory hose, s (zeros for a static hose).
    pub fn taus_s(&self) -> [f64; N_FILTERS] {
        self.taus_s
    }

    /// Spread sigma of the network.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// Number of training samples.
    pub fn n_samples(&self) -> usize {
        self.n_samples
    }

    /// Extreme training outputs (g_min, g_max), mm^3/s.
    pub fn output_range_mm3ps(&self) -> (f64, f64) {
        (self.g_min, self.g_max)
    }

    /// Bound on |evaluated - direct GRNN sum| of the wall rate, mm^3/s.
    pub fn error_bound_mm3ps(&self) -> f64 {
        self.bound
    }

    /// Newton's step tolerance of [`GrnnHose::solve_dp_paps`], Pa/s
    /// ([`NEWTON_STEP_TOL_PAPS`] for a static hose, [`MEMORY_NEWTON_TOL_PAPS`]
    /// for a memory hose).
    pub fn newton_tol_paps(&self) -> f64 {
        self.newton_tol_paps
    }

    /// Whether the plant predicts each solve's warm start from the line's
    /// previous solve (true for a memory hose; see
    /// [`crate::model::plant::Plant`]'s GRNN lines).
    pub fn predicts_warm_start(&self) -> bool {
        self.predict_warm
    }

    /// This hose with another Newton tolerance (Pa/s, > 0) and warm-start
    /// predictor setting (for comparisons of the solver against a tighter one).
    pub fn with_newton(mut self, tol_paps: f64, predict_warm: bool) -> Self {
        assert!(tol_paps > 0.0, "the Newton tolerance must be positive");
        self.newton_tol_paps = tol_paps;
        self.predict_warm = predict_warm;
        self
    }

    /// Whether a plant evaluates this hose through caches that take
    /// Taylor steps from their last exact evaluation
    /// ([`LocalCache::with_taylor`]; true for a memory hose evaluated by
    /// [`LocalGrnn`], within the same bound).
    pub fn taylor_steps(&self) -> bool {
        self.taylor_steps && matches!(self.eval, Evaluator::Local { .. })
    }

    /// This hose with Taylor steps in the plant on or off (off: every
    /// evaluation summed, for comparisons).
    pub fn with_taylor_steps(mut self, on: bool) -> Self {
        self.taylor_steps = on;
        self
    }

    /// What the hose was fitted on.
    pub fn description(&self) -> &str {
        &self.description
    }

    /// Wall rate g [mm^3/s] and its slope dg/d(dP/dt) [mm^3/s per MPa/s] at
    /// pressure `p_mpa`, rate `dpdt_mpa_s` and (memory hose) the filter
    /// deviations `mem_mpa` = P - lowpass(P, tau_k) (ignored by a static hose).
    /// The same values as [`GrnnHose::wall_rate_cached`] (slower for a memory
    /// hose: its list is built for this one call).
    pub fn wall_rate(&self, p_mpa: f64, dpdt_mpa_s: f64, mem_mpa: [f64; N_FILTERS]) -> (f64, f64) {
        self.wall_rate_cached(p_mpa, dpdt_mpa_s, mem_mpa, &mut LocalCache::new())
    }

    /// [`GrnnHose::wall_rate`] through `cache` (used by a memory hose's
    /// [`LocalGrnn`]; give each query stream, e.g. each hose line, its own).
    /// Through a plain cache ([`LocalCache::new`]) the result does not depend
    /// on the cache's state; through a Taylor cache
    /// ([`LocalCache::with_taylor`]) it may be a Taylor step from the cache's
    /// last exact evaluation, within the same bound.
    #[inline]
    pub fn wall_rate_cached(
        &self,
        p_mpa: f64,
        dpdt_mpa_s: f64,
        mem_mpa: [f64; N_FILTERS],
        cache: &mut LocalCache,
    ) -> (f64, f64) {
        match &self.eval {
            Evaluator::Table(f) => {
                let (g, grad) = f.eval([p_mpa, dpdt_mpa_s]);
                (g, grad[1])
            }
            Evaluator::Trunc { trunc, z } => {
                let e = trunc.eval_z(&z.apply(p_mpa, dpdt_mpa_s, mem_mpa), false);
                (e.y, e.grad[1] * z.inv_std[1])
            }
            Evaluator::Local { local, z } => {
                let e = local.eval_z(&z.apply(p_mpa, dpdt_mpa_s, mem_mpa), cache);
                (e.y, e.dy_du1 * z.inv_std[1])
            }
        }
    }

    /// Solve a dP + 1e-9 g(1e-6 P, 1e-6 dP, mem) = Q for dP [Pa/s] (module
    /// documentation), with a = V/beta_e [m^3/Pa], Q [m^3/s], starting at `warm_paps`.
    pub fn solve_dp_paps(
        &self,
        p_pa: f64,
        mem_mpa: [f64; N_FILTERS],
        q_m3ps: f64,
        a_m3ppa: f64,
        warm_paps: f64,
    ) -> Solve {
        let mut cache = LocalCache::new();
        self.solve_dp_paps_cached(p_pa, mem_mpa, q_m3ps, a_m3ppa, warm_paps, &mut cache)
    }

    /// [`GrnnHose::solve_dp_paps`] with the evaluations through `cache` (the same
    /// result through a plain cache, see [`GrnnHose::wall_rate_cached`]).
    pub fn solve_dp_paps_cached(
        &self,
        p_pa: f64,
        mem_mpa: [f64; N_FILTERS],
        q_m3ps: f64,
        a_m3ppa: f64,
        warm_paps: f64,
        cache: &mut LocalCache,
    ) -> Solve {
        let p_mpa = p_pa * 1e-6;
        let mut lo = (q_m3ps - 1e-9 * self.g_max) / a_m3ppa;
        let mut hi = (q_m3ps - 1e-9 * self.g_min) / a_m3ppa;
        let mut x = if warm_paps.is_finite() {
            warm_paps.clamp(lo, hi)
        } else {
            0.5 * (lo + hi)
        };
        let mut last_fp = a_m3ppa;
        for it in 1..=NEWTON_MAX_ITER {
            let (g, slope) = self.wall_rate_cached(p_mpa, x * 1e-6, mem_mpa, cache);
            let f = a_m3ppa * x + 1e-9 * g - q_m3ps;
            let fp = a_m3ppa + 1e-15 * slope;
            if f == 0.0 {
                return Solve {
                    dp_paps: x,
                    iterations: it,
                    df_ddp_m3ppa: fp,
                };
            }
            if f > 0.0 {
                hi = x;
            } else {
                lo = x;
            }
            let newton = x - f / fp;
            // A Newton step that rounds to zero ends the iteration at x (x has
            // just become an end of the bracket, so the test below would
            // otherwise send it to bisection, away from the root).
            if fp > 0.0 && newton == x {
                return Solve {
                    dp_paps: x,
                    iterations: it,
                    df_ddp_m3ppa: fp,
                };
            }
            let next = if fp > 0.0 && newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            let step = (next - x).abs();
            x = next;
            if step < self.newton_tol_paps {
                return Solve {
                    dp_paps: x,
                    iterations: it,
                    df_ddp_m3ppa: fp,
                };
            }
            last_fp = fp;
        }
        Solve {
            dp_paps: x,
            iterations: NEWTON_MAX_ITER,
            df_ddp_m3ppa: last_fp,
        }
    }
}

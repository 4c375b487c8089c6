//! MPC run-time law (docs/model.md section 6.4), f32, precomputed gains only.
//!
//! At each MPC tick:
//! ```text
//! du    = Ky r - Kmpc [dxm; y] = Ky (r - y) - Kx dxm
//! du    = clamp(du, -v_max Ts, v_max Ts)
//! u_new = clamp(u + du, X_min, X_max);  du = u_new - u
//! v_cmd = du / Ts                       (held until the next MPC tick)
//! ```
//! The manipulated variable u is the power-piston position Xi; the clamps on
//! du and u are the speed and stroke saturations, and because the state
//! increment is taken from the applied u they are also the anti-windup.

use crate::design::{DesignError, Mat3, MpcDesign, MpcParams, Vec3};
use crate::params::PlantParams;

/// Where the MPC takes its state increment from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateSource {
    /// Plain MPC: the prediction model run open loop on the applied u (Wang 2009).
    Model,
    /// MPC-ESO: the observed state [Xo, z2, z3 + b0 v_cmd - B2 u].
    Eso,
}

/// Saturation limits shared by every controller.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Ball-screw speed limit, m/s.
    pub v_max_mps: f32,
    /// Lower stroke limit of the power piston, m.
    pub x_min_m: f32,
    /// Upper stroke limit of the power piston, m.
    pub x_max_m: f32,
}

impl Limits {
    /// The limits of the nominal plant.
    pub fn from_plant(p: &PlantParams) -> Self {
        Self {
            v_max_mps: p.v_max_mps as f32,
            x_min_m: p.x_min_m as f32,
            x_max_m: p.x_max_m as f32,
        }
    }

    /// True when the limits are finite, positive speed and ordered stroke.
    pub fn is_valid(&self) -> bool {
        self.v_max_mps.is_finite()
            && self.v_max_mps > 0.0
            && self.x_min_m.is_finite()
            && self.x_max_m.is_finite()
            && self.x_min_m < self.x_max_m
    }
}

/// Precomputed MPC gains and model, f32 (the run-time configuration).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MpcGains {
    /// State-increment gain Kx.
    pub kx: [f32; 3],
    /// Reference gain Ky.
    pub ky: f32,
    /// Sample time Ts, s.
    pub ts_s: f32,
    /// Discrete model (for the plain MPC's open-loop model).
    pub ad: [[f32; 3]; 3],
    /// Discrete input vector.
    pub bd: [f32; 3],
    /// B2 of the prediction model (maps u into the third state), 1/s^2.
    pub b2_gain: f32,
}

fn to_f32_mat(m: &Mat3) -> [[f32; 3]; 3] {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = m[(i, j)] as f32;
        }
    }
    out
}

fn to_f32_vec(v: &Vec3) -> [f32; 3] {
    [v[0] as f32, v[1] as f32, v[2] as f32]
}

impl MpcGains {
    /// Design (f64) and round the result to the f32 run-time gains.
    pub fn design(plant: &PlantParams, params: MpcParams) -> Result<Self, DesignError> {
        Ok(Self::from_design(&MpcDesign::new(plant, params)?))
    }

    /// The run-time gains of a finished design.
    pub fn from_design(d: &MpcDesign) -> Self {
        Self {
            kx: [d.kx[0] as f32, d.kx[1] as f32, d.kx[2] as f32],
            ky: d.ky as f32,
            ts_s: d.params.ts_s as f32,
            ad: to_f32_mat(&d.ad),
            bd: to_f32_vec(&d.bd),
            b2_gain: d.model.b2_gain as f32,
        }
    }
}

/// MPC run-time state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Mpc {
    /// Last power-piston position command u, m.
    pub u_m: f32,
    /// Model state (plain MPC).
    pub xm: [f32; 3],
    /// State at the previous MPC tick.
    pub xm_prev: [f32; 3],
    /// True until the first MPC tick has run.
    pub started: bool,
}

/// The ESO's estimates as the MPC-ESO uses them (docs/model.md section 6.4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observed {
    /// Estimated actuating piston speed z2, m/s.
    pub z2_mps: f32,
    /// Estimated total disturbance z3, m/s^2.
    pub z3_mps2: f32,
    /// b0 times the command in force, m/s^2.
    pub b0_v_mps2: f32,
}

/// Result of one MPC tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MpcOutput {
    /// Drive speed command, m/s.
    pub v_cmd_mps: f32,
    /// True when a speed or stroke clamp was active.
    pub saturated: bool,
}

impl Mpc {
    /// Start from rest with the power piston at `u0_m`.
    pub fn new(u0_m: f32) -> Self {
        Self {
            u_m: u0_m,
            ..Self::default()
        }
    }

    /// One MPC tick. `y_m` is the measured Xo, `r_m` the reference; `observed`
    /// is the ESO's estimate for MPC-ESO, `None` for the plain MPC.
    pub fn tick(
        &mut self,
        g: &MpcGains,
        lim: &Limits,
        y_m: f32,
        r_m: f32,
        observed: Option<Observed>,
    ) -> MpcOutput {
        let (x_now, source) = match observed {
            Some(o) => (
                [
                    y_m,
                    o.z2_mps,
                    o.z3_mps2 + o.b0_v_mps2 - g.b2_gain * self.u_m,
                ],
                StateSource::Eso,
            ),
            None => (self.xm, StateSource::Model),
        };
        let dx = if !self.started {
            [0.0; 3]
        } else {
            let mut dx = [
                x_now[0] - self.xm_prev[0],
                x_now[1] - self.xm_prev[1],
                x_now[2] - self.xm_prev[2],
            ];
            if source == StateSource::Eso {
                dx[0] = y_m - self.xm_prev[0];
            }
            dx
        };
        let du_raw = g.ky * (r_m - y_m) - (g.kx[0] * dx[0] + g.kx[1] * dx[1] + g.kx[2] * dx[2]);
        let du_max = lim.v_max_mps * g.ts_s;
        let du_sat = clamp(du_raw, -du_max, du_max);
        let u_free = self.u_m + du_sat;
        let u_new = clamp(u_free, lim.x_min_m, lim.x_max_m);
        let du = u_new - self.u_m;
        // From the clamps themselves (u_new - u differs from du by rounding).
        let saturated = du_sat != du_raw || u_new != u_free;
        match source {
            StateSource::Model => {
                // The plain MPC's model state is xm; docs/model.md 6.4 starts it at 0
                // and counts dxm from the first tick (xm_prev = xm = 0 then).
                self.xm_prev = self.xm;
                self.xm = mat_vec_add(&g.ad, &self.xm, &g.bd, u_new);
            }
            StateSource::Eso => self.xm_prev = x_now,
        }
        self.u_m = u_new;
        self.started = true;
        MpcOutput {
            v_cmd_mps: du / g.ts_s,
            saturated,
        }
    }
}

fn mat_vec_add(a: &[[f32; 3]; 3], x: &[f32; 3], b: &[f32; 3], u: f32) -> [f32; 3] {
    let mut out = [0.0; 3];
    for i in 0..3 {
        out[i] = a[i][0] * x[0] + a[i][1] * x[1] + a[i][2] * x[2] + b[i] * u;
    }
    out
}

/// Clamp that maps NaN to the lower bound (callers check finiteness first;
/// this only keeps a stray NaN from propagating).
pub fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    if x > hi {
        hi
    } else if x >= lo {
        x
    } else {
        lo
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    fn paper_gains() -> MpcGains {
        MpcGains::design(
            &PlantParams::NOMINAL,
            MpcParams {
                np: 6,
                nc: 2,
                ts_s: 0.1,
                rw: 33.0,
            },
        )
        .unwrap()
    }

    #[test]
    fn first_tick_moves_by_ky_times_error_within_speed_limit() {
        let g = paper_gains();
        let lim = Limits::from_plant(&PlantParams::NOMINAL);
        let mut mpc = Mpc::new(0.0);
        let out = mpc.tick(&g, &lim, 0.0, 0.05, None);
        // Ky * 0.05 = 8.0e-3 m per 0.1 s, under v_max Ts = 0.01 m.
        assert!((out.v_cmd_mps - g.ky * 0.05 / 0.1).abs() < 1e-6);
        assert!(!out.saturated);
        assert_eq!(mpc.u_m, g.ky * 0.05);
    }

    #[test]
    fn speed_clamp_limits_du_and_reports_it() {
        let g = paper_gains();
        let lim = Limits::from_plant(&PlantParams::NOMINAL);
        let mut mpc = Mpc::new(0.0);
        let out = mpc.tick(&g, &lim, 0.0, 1.0, None);
        assert!((out.v_cmd_mps - 0.1).abs() < 1e-6);
        assert!(out.saturated);
    }

    #[test]
    fn stroke_clamp_holds_u_inside_and_zero_speed_at_the_end() {
        let g = paper_gains();
        let lim = Limits::from_plant(&PlantParams::NOMINAL);
        let mut mpc = Mpc::new(0.109);
        let out = mpc.tick(&g, &lim, 0.0, 1.0, None);
        assert!((mpc.u_m - 0.11).abs() < 1e-7);
        assert!(out.v_cmd_mps <= 0.0101);
        let out = mpc.tick(&g, &lim, 0.0, 1.0, None);
        assert_eq!(mpc.u_m, 0.11);
        assert!(out.v_cmd_mps.abs() < 1e-6);
    }

    #[test]
    fn clamp_maps_nan_to_lower_bound() {
        assert_eq!(clamp(f32::NAN, -1.0, 1.0), -1.0);
        assert_eq!(clamp(2.0, -1.0, 1.0), 1.0);
        assert_eq!(clamp(0.5, -1.0, 1.0), 0.5);
    }
}

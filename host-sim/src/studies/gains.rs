//! `host-sim gains`: the MPC design of docs/model.md section 6.3 as JSON
//! (docs/interfaces.md section 4).

use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use dca_core::design::{DesignError, MpcDesign, MpcParams};
use serde_json::{json, Map, Value};

/// Optional overrides of the preset's MPC parameters (applied to both designs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GainOverrides {
    /// Prediction horizon Np.
    pub np: Option<usize>,
    /// Control horizon Nc.
    pub nc: Option<usize>,
    /// Sample time Ts, s.
    pub ts_s: Option<f64>,
    /// Input weight r_w.
    pub rw: Option<f64>,
}

impl GainOverrides {
    fn apply(&self, p: MpcParams) -> MpcParams {
        MpcParams {
            np: self.np.unwrap_or(p.np),
            nc: self.nc.unwrap_or(p.nc),
            ts_s: self.ts_s.unwrap_or(p.ts_s),
            rw: self.rw.unwrap_or(p.rw),
        }
    }
}

fn rows<const R: usize, const C: usize>(
    m: &nalgebra::SMatrix<f64, R, C>,
    nr: usize,
    nc: usize,
) -> Value {
    Value::Array(
        (0..nr)
            .map(|i| Value::Array((0..nc).map(|j| json!(m[(i, j)])).collect()))
            .collect(),
    )
}

/// The JSON object of one design: matrices as row-major nested arrays.
pub fn design_json(name: &str, d: &MpcDesign) -> Value {
    let p = d.params;
    json!({
        "controller": name,
        "np": p.np,
        "nc": p.nc,
        "ts_s": p.ts_s,
        "rw": p.rw,
        "Ad": rows(&d.ad, 3, 3),
        "Bd": rows(&d.bd, 3, 1),
        "A": rows(&d.a, 4, 4),
        "B": rows(&d.b, 4, 1),
        "C": rows(&d.c, 1, 4),
        "F": rows(&d.f, p.np, 4),
        "Phi": rows(&d.phi, p.np, p.nc),
        "Kx": d.kx,
        "Ky": d.ky,
        "Kmpc": [d.kx[0], d.kx[1], d.kx[2], d.ky_state],
    })
}

/// A design the overrides made impossible.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{} design refused: {}", kind.name(), error.as_str())]
pub struct GainsError {
    /// The MPC variant.
    pub kind: ControllerKind,
    /// Why.
    pub error: DesignError,
}

/// Design both MPC variants of a preset and return `{"mpc": {...}, "mpc-eso": {...}}`.
pub fn gains(preset: Preset, over: &GainOverrides) -> Result<Value, GainsError> {
    let mut out = Map::new();
    for kind in [ControllerKind::Mpc, ControllerKind::MpcEso] {
        let cfg = ControllerConfig::preset(preset, kind);
        let params = over.apply(cfg.active_mpc());
        let d = MpcDesign::new(&cfg.plant, params).map_err(|error| GainsError { kind, error })?;
        out.insert(kind.name().to_string(), design_json(kind.name(), &d));
    }
    Ok(Value::Object(out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_json_has_the_contract_fields() {
        let v = gains(Preset::Paper, &GainOverrides::default()).unwrap();
        for name in ["mpc", "mpc-eso"] {
            let o = &v[name];
            for key in [
                "Ad", "Bd", "A", "B", "C", "F", "Phi", "Kx", "Ky", "np", "nc", "ts_s", "rw",
            ] {
                assert!(!o[key].is_null(), "{name}.{key}");
            }
        }
        assert_eq!(v["mpc"]["np"], 6);
        assert_eq!(v["mpc-eso"]["nc"], 3);
        assert_eq!(v["mpc-eso"]["F"].as_array().unwrap().len(), 8);
        assert_eq!(v["mpc-eso"]["Phi"][7].as_array().unwrap().len(), 3);
        let ky = v["mpc"]["Ky"].as_f64().unwrap();
        assert!((ky - 0.1604827894).abs() < 1e-9);
    }

    #[test]
    fn overrides_apply_and_bad_ones_are_refused() {
        let over = GainOverrides {
            np: Some(10),
            nc: Some(4),
            ts_s: Some(0.01),
            rw: Some(300.0),
        };
        let v = gains(Preset::Paper, &over).unwrap();
        assert_eq!(v["mpc"]["np"], 10);
        assert_eq!(v["mpc"]["ts_s"], 0.01);
        let bad = GainOverrides {
            nc: Some(0),
            ..GainOverrides::default()
        };
        let err = gains(Preset::Paper, &bad).unwrap_err().to_string();
        assert!(err.contains("control horizon"), "{err}");
    }
}

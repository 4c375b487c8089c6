//! Controller configuration files ([`ConfigFile`], TOML) and sweep parameters
//! ([`SweepParam::parse`], `path=v1,v2,...`, which go through the same TOML
//! format), on arbitrary text (the input as UTF-8, invalid sequences
//! replaced).
//!
//! The whole input is parsed as a configuration file, and each of its first
//! lines as a sweep parameter.
//!
//! Invariants:
//! * no panic, no hang;
//! * errors name the file, and a line that exists in the text;
//! * an accepted file resolves for every controller kind exactly when its
//!   preset is known; a resolved configuration either is refused by
//!   [`Controller::new`] or gives a controller whose commands are finite and
//!   within its speed limit, whatever it is fed;
//! * an accepted sweep parameter has a path of the board's settings table
//!   (`table.key`, or `table.group.key` as `model.hose.ce0_m3pp`) and finite
//!   values, each of which the sweep accepts on its own (the sweep applies
//!   each one separately).

use dca_core::controller::{Controller, ControllerKind, Sample};
use host_sim::sim::batch::SweepParam;
use host_sim::sim::config::{ConfigFile, FileError};

use super::{line_limit, text};

const FILE: &str = "fuzz.toml";

/// Sweep parameters tried per input (one per line).
const MAX_SWEEP_LINES: usize = 4;

/// `e` names `file` (and a line of `text`, if any).
pub(crate) fn check_file_error(e: &FileError, file: &str, text: &str) {
    assert_eq!(e.file, file, "{e}");
    assert!(e.to_string().starts_with(file), "{e}");
    assert!(!e.message.is_empty(), "{e:?}");
    if let Some(l) = e.line {
        assert!(
            l >= 1 && l <= line_limit(text),
            "line {l} of a text of {} lines: {e}",
            text.lines().count()
        );
    }
}

/// Design a controller from `cfg` at the simulator's and at the board's base
/// tick and drive it with plausible and absurd samples.
pub(crate) fn check_controller(cfg: &dca_core::controller::ControllerConfig) {
    for base_dt_s in [1e-4, 1e-3] {
        let mut cfg = *cfg;
        cfg.base_dt_s = base_dt_s;
        let Ok(mut c) = Controller::new(&cfg) else {
            continue;
        };
        assert_eq!(c.kind(), cfg.kind);
        let v_max = cfg.limits.v_max_mps;
        let samples = [
            (0.0, 0.05),
            (0.01, 0.05),
            (0.2, -0.1),
            (f32::NAN, 0.05),
            (0.02, f32::INFINITY),
            (-1.0e30, 1.0e30),
        ];
        for k in 0..64 {
            let (xo, r) = samples[k / 8 % samples.len()];
            let s = Sample {
                xo_m: xo,
                xi_m: xo,
                p1_pa: 1.0e6,
                p2_pa: 1.0e6,
                ft_n: 0.0,
            };
            let out = c.step(&s, r);
            assert!(
                out.v_cmd_mps.is_finite() && out.v_cmd_mps.abs() <= v_max,
                "{:?}: command {} (v_max {v_max}) for xo {xo}, r {r}",
                cfg.kind,
                out.v_cmd_mps
            );
        }
    }
}

/// Check a parsed configuration (a file, or a scenario's `[controller]`).
pub(crate) fn check_config(c: &ConfigFile, file: &str, text: &str) {
    let preset = c.preset(file);
    if let Err(e) = &preset {
        check_file_error(e, file, text);
        assert_eq!(e.field.as_deref(), Some("preset"));
    }
    if let Err(e) = c.kind(file) {
        check_file_error(&e, file, text);
        assert_eq!(e.field.as_deref(), Some("controller"));
    }
    for kind in ControllerKind::ALL {
        match c.resolve(kind, file) {
            Ok(cfg) => {
                assert!(preset.is_ok(), "resolved with an unknown preset");
                assert_eq!(cfg.kind, kind);
                check_controller(&cfg);
            }
            Err(e) => {
                assert!(preset.is_err(), "refused with a known preset: {e}");
                check_file_error(&e, file, text);
            }
        }
    }
}

fn check_sweep(line: &str) {
    let Ok(p) = SweepParam::parse(line) else {
        return;
    };
    let parts: Vec<&str> = p.path.split('.').collect();
    assert!(
        (2..=3).contains(&parts.len()) && parts.iter().all(|s| !s.is_empty()),
        "{line:?}: path {:?}",
        p.path
    );
    assert!(
        dca_app::settings::PARAMS.iter().any(|q| q.name == p.path),
        "{line:?}: path {:?} is not a setting",
        p.path
    );
    assert!(!p.values.is_empty(), "{line:?}: no values");
    for v in &p.values {
        assert!(v.is_finite(), "{line:?}: value {v}");
        let one = format!("{}={v:?}", p.path);
        if let Err(e) = SweepParam::parse(&one) {
            panic!("{line:?} accepted, but its value {v:?} alone is refused: {e}");
        }
    }
}

/// The configuration harness; see the module documentation.
pub fn config_toml(data: &[u8]) {
    let text = text(data);
    match ConfigFile::parse_str(&text, FILE) {
        Ok(c) => check_config(&c, FILE, &text),
        Err(e) => check_file_error(&e, FILE, &text),
    }
    for line in text.lines().take(MAX_SWEEP_LINES) {
        check_sweep(line);
    }
}

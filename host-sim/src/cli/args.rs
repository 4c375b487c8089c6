//! Options and argument checks shared by several subcommands.

use std::path::{Path, PathBuf};

use host_sim::io::num::Num;
use host_sim::sim::request::RunRequest;

/// The options that choose a simulated run (shared by run, sweep and hil).
#[derive(clap::Args, Debug)]
pub struct RunOpts {
    /// Scenario: step, sine, stepload, sineload, openloop, or a TOML file.
    #[arg(long)]
    scenario: String,
    /// Controller: mpc-eso, mpc, pid, fuzzy-pid or cmpc-eso (else the scenario file's).
    #[arg(long)]
    controller: Option<String>,
    /// Configuration: paper, fast, limit or a TOML file (default paper).
    #[arg(long)]
    config: Option<String>,
    /// Hose model of the plant: nonlinear (default), linear, rigid, grnn, grnn-memory.
    #[arg(long)]
    hose: Option<String>,
    /// Sensor mode: ideal (default) or realistic.
    #[arg(long)]
    sensors: Option<String>,
    /// An unmodelled effect (repeatable): `name` with typical parameters or
    /// `name:param=value,...`, e.g. leakage:g_m3pspa=1e-13 (docs/model.md section 12).
    #[arg(long = "effect")]
    effects: Vec<String>,
    /// The rig's physical parameters: a TOML file of PlantParams keys (and
    /// [hose]); replaces the scenario file's [plant.params] (default: nominal).
    #[arg(long, value_name = "FILE.toml")]
    plant: Option<String>,
}

impl RunOpts {
    /// The options as given, `--key value ...` (for reports).
    pub fn describe(&self) -> String {
        let mut s = format!("--scenario {}", self.scenario);
        for (k, v) in [
            ("controller", &self.controller),
            ("config", &self.config),
            ("hose", &self.hose),
            ("sensors", &self.sensors),
            ("plant", &self.plant),
        ] {
            if let Some(v) = v {
                s += &format!(" --{k} {v}");
            }
        }
        for e in &self.effects {
            s += &format!(" --effect {e}");
        }
        s
    }

    /// Check that every file these options name can be read (see
    /// [`input_file`]): the scenario and configuration when they are TOML
    /// files, and the plant file.
    pub fn check_files(&self) -> anyhow::Result<()> {
        for (option, value) in [
            ("--scenario", Some(&self.scenario)),
            ("--config", self.config.as_ref()),
        ] {
            if let Some(v) = value.filter(|v| v.ends_with(".toml")) {
                input_file(option, Path::new(v))?;
            }
        }
        if let Some(p) = &self.plant {
            input_file("--plant", Path::new(p))?;
        }
        Ok(())
    }

    /// The run request with a seed, a plant step and a control tick.
    pub fn request(
        self,
        seed: Option<u64>,
        dt_s: Option<f64>,
        control_tick_s: Option<f64>,
    ) -> RunRequest {
        RunRequest {
            scenario: self.scenario,
            controller: self.controller,
            config: self.config,
            hose: self.hose,
            sensors: self.sensors,
            seed,
            dt_s,
            control_tick_s,
            effects: self.effects,
            plant: self.plant,
        }
    }
}

/// Help of `--control-tick` (run and sweep).
pub const CONTROL_TICK_HELP: &str = "The controller's tick in seconds (default 0.001, the \
     board's). A finer tick (a whole number of plant steps dividing 1 ms, e.g. 0.0001) is a \
     study of what the board cannot do: its runs no longer predict the board";

/// A positive, finite number of seconds (at most an hour).
pub fn seconds(s: f64, what: &str) -> anyhow::Result<std::time::Duration> {
    if s.is_finite() && s > 0.0 && s <= 3600.0 {
        Ok(std::time::Duration::from_secs_f64(s))
    } else {
        anyhow::bail!("{what} {}: expected seconds in (0, 3600]", Num(s))
    }
}

/// The canonical path of the file given with `option`, or an error that
/// names the option and the path as given: `--fit out/a.csv: no such file`.
pub fn input_file(option: &str, path: &Path) -> anyhow::Result<PathBuf> {
    let fail = |why: String| anyhow::anyhow!("{option} {}: {why}", path.display());
    let canonical = std::fs::canonicalize(path).map_err(|e| {
        fail(match e.kind() {
            std::io::ErrorKind::NotFound => "no such file".into(),
            std::io::ErrorKind::PermissionDenied => "permission denied".into(),
            _ => e.to_string(),
        })
    })?;
    if canonical.is_dir() {
        return Err(fail("is a directory, not a file".into()));
    }
    Ok(canonical)
}

/// The controller preset named by `--config` (`paper`, `fast` or `limit`).
pub fn preset(config: &str) -> anyhow::Result<dca_core::controller::Preset> {
    dca_core::controller::Preset::from_name(config).ok_or_else(|| {
        anyhow::anyhow!("unknown --config '{config}': expected paper, fast or limit")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_input_names_its_option() {
        let e = input_file("--fit", Path::new("out/no-such-run.csv"))
            .unwrap_err()
            .to_string();
        assert_eq!(e, "--fit out/no-such-run.csv: no such file");
        let dir = std::env::temp_dir();
        let e = input_file("--plant", &dir).unwrap_err().to_string();
        assert!(e.ends_with(": is a directory, not a file"), "{e}");
        let file = dir.join(format!("dca-args-{}.toml", std::process::id()));
        std::fs::write(&file, "").unwrap();
        let c = input_file("--plant", &file).unwrap();
        assert_eq!(c, std::fs::canonicalize(&file).unwrap());
        std::fs::remove_file(&file).ok();
    }

    #[test]
    fn seconds_out_of_range_are_readable() {
        let e = seconds(1e300, "--timeout").unwrap_err().to_string();
        assert_eq!(e, "--timeout 1e300: expected seconds in (0, 3600]");
        assert!(seconds(f64::NAN, "--timeout").is_err());
        assert!(seconds(2.0, "--timeout").is_ok());
    }
}

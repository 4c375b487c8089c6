//! Options and argument checks shared by several subcommands.

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

    /// The run request with a seed and a plant step.
    pub fn request(self, seed: Option<u64>, dt_s: Option<f64>) -> RunRequest {
        RunRequest {
            scenario: self.scenario,
            controller: self.controller,
            config: self.config,
            hose: self.hose,
            sensors: self.sensors,
            seed,
            dt_s,
            effects: self.effects,
            plant: self.plant,
        }
    }
}

/// A positive, finite number of seconds (at most an hour).
pub fn seconds(s: f64, what: &str) -> anyhow::Result<std::time::Duration> {
    if s.is_finite() && s > 0.0 && s <= 3600.0 {
        Ok(std::time::Duration::from_secs_f64(s))
    } else {
        anyhow::bail!("{what} {s}: expected seconds in (0, 3600]")
    }
}

/// The controller preset named by `--config` (`paper`, `fast` or `limit`).
pub fn preset(config: &str) -> anyhow::Result<dca_core::controller::Preset> {
    dca_core::controller::Preset::from_name(config).ok_or_else(|| {
        anyhow::anyhow!("unknown --config '{config}': expected paper, fast or limit")
    })
}

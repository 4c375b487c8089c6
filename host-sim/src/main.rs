//! host-sim command line: thin wrappers around library functions.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use dca_core::controller::Preset;
use host_sim::batch::{sweep, write_csv, SweepParam};
use host_sim::gains::{gains, GainOverrides};
use host_sim::paper::{run_paper, table_markdown, PaperOptions};
use host_sim::run::{execute, trace_metrics, RunRequest};
use std::path::PathBuf;

/// The options that choose a simulated run (shared by run, sweep and hil).
#[derive(clap::Args, Debug)]
struct RunOpts {
    /// Scenario: step, sine, stepload, sineload, openloop, or a TOML file.
    #[arg(long)]
    scenario: String,
    /// Controller: mpc-eso, mpc, pid or fuzzy-pid (else the scenario file's).
    #[arg(long)]
    controller: Option<String>,
    /// Configuration: paper, fast or a TOML file (default paper).
    #[arg(long)]
    config: Option<String>,
    /// Hose model of the plant: nonlinear (default), linear, rigid, grnn, grnn-memory.
    #[arg(long)]
    hose: Option<String>,
    /// Sensor mode: ideal (default) or realistic.
    #[arg(long)]
    sensors: Option<String>,
    /// An unmodelled effect (repeatable): `name` with typical parameters or
    /// `name:param=value,...`, e.g. leakage:g_m3pspa=1e-13 (plant.md section 12).
    #[arg(long = "effect")]
    effects: Vec<String>,
}

impl RunOpts {
    fn request(self, seed: Option<u64>, dt_s: Option<f64>) -> RunRequest {
        RunRequest {
            scenario: self.scenario,
            controller: self.controller,
            config: self.config,
            hose: self.hose,
            sensors: self.sensors,
            seed,
            dt_s,
            effects: self.effects,
        }
    }
}

/// Simulator and tools for the miniature double-cylinder hydraulic actuator.
#[derive(Parser, Debug)]
#[command(name = "host-sim", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The hose models of plant.md section 9: GRNN, RBF and BP side by side
    /// (the paper's Fig. 9), the GRNN with memory on the dynamic data, and the
    /// closed-loop deviation after the 800 N step with each hose.
    Hose {
        /// Quasi-static hose data (default: the shipped sample data).
        #[arg(long)]
        quasistatic: Option<PathBuf>,
        /// Dynamic hose data (default: the shipped sample data).
        #[arg(long)]
        dynamic: Option<PathBuf>,
        /// Report directory.
        #[arg(long, default_value = "out/hose")]
        out: PathBuf,
        /// Also the leave-one-run-out comparison of the static and memory GRNNs
        /// (about 1.5 minutes).
        #[arg(long)]
        memory: bool,
        /// Also the closed-loop comparison of the hose models (MPC-ESO, stepload).
        #[arg(long)]
        closed_loop: bool,
    },
    /// The gap diagnosis's validation suite: synthetic runs with hidden
    /// effects; prints the confusion table.
    GapSuite {
        /// Also write the table to this Markdown file.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Hardware- or processor-in-the-loop: the plant here, the control tick on a
    /// board (--port) or in the emulated firmware (--qemu), in lockstep.
    Hil {
        /// Serial device of the board's HIL link (e.g. /dev/ttyACM0).
        #[arg(long, conflicts_with = "qemu")]
        port: Option<String>,
        /// Serial device of the board's console: the run sets the board up itself.
        #[arg(long, requires = "port")]
        console: Option<String>,
        /// Longest wait for a reply on the HIL link, s.
        #[arg(long, default_value_t = 2.0)]
        timeout: f64,
        /// Set the firmware's link timeout (`hil.timeout_ms`) through the console
        /// before arming (needs --console or --qemu; default: the board's setting).
        #[arg(long)]
        link_timeout_ms: Option<u32>,
        /// Start the emulated firmware (QEMU netduinoplus2) instead of a board.
        #[arg(long)]
        qemu: bool,
        /// The emulated firmware's ELF (default: built with `cargo fw-qemu` if missing).
        #[arg(long, requires = "qemu")]
        elf: Option<PathBuf>,
        /// What to simulate.
        #[command(flatten)]
        what: RunOpts,
        /// Noise seed.
        #[arg(long)]
        seed: Option<u64>,
        /// Also run the same loop in software and check the drive commands are
        /// bit-identical.
        #[arg(long)]
        compare: bool,
        /// Where to write the run log (CSV).
        #[arg(long)]
        log: PathBuf,
    },
    /// The board's command console from this terminal (interfaces.md section 5):
    /// interactive with line editing and history, or a script; the telemetry
    /// stream captured as a run log.
    Console {
        /// Serial device of the board's console (USART1), e.g. /dev/ttyUSB0.
        #[arg(long, conflicts_with = "qemu", required_unless_present = "qemu")]
        port: Option<String>,
        /// Baud rate of the console.
        #[arg(long, default_value_t = 115_200, requires = "port")]
        baud: u32,
        /// Start the emulated firmware (QEMU netduinoplus2) instead of a board.
        #[arg(long)]
        qemu: bool,
        /// The emulated firmware's ELF (default: built with `cargo fw-qemu` if missing).
        #[arg(long, requires = "qemu")]
        elf: Option<PathBuf>,
        /// Send the lines of FILE one by one, each waiting for its reply
        /// (blank lines and `#` comments skipped; `sleep S` pauses S seconds).
        #[arg(long)]
        script: Option<PathBuf>,
        /// Write the telemetry stream (after `telemetry on`) to this run log.
        #[arg(long)]
        capture: Option<PathBuf>,
        /// Longest wait for a reply, s.
        #[arg(long, default_value_t = 10.0)]
        timeout: f64,
    },
    /// Sim-to-real gap diagnosis of recorded run logs (interfaces.md section 2).
    Gap {
        /// A run log used to localise the gap and fit the candidate effects (repeatable).
        #[arg(long = "fit", required = true)]
        fit: Vec<PathBuf>,
        /// A held-out run log, only used to evaluate what was fitted (repeatable).
        #[arg(long = "check", required = true)]
        check: Vec<PathBuf>,
        /// Where to write the JSON report.
        #[arg(long)]
        json: PathBuf,
        /// Directory for the Markdown report with plots.
        #[arg(long)]
        report: Option<PathBuf>,
    },
    /// Benchmarks of the simulator (real-time factors, derivative cost, batch
    /// speed-up), printed as a table.
    Bench {
        /// Repetitions of each measurement (the best is kept).
        #[arg(long, default_value_t = 5)]
        reps: usize,
    },
    /// Parameter sweep and/or Monte Carlo over noise seeds, on every core;
    /// one CSV row of metrics per run.
    Sweep {
        /// What to simulate.
        #[command(flatten)]
        what: RunOpts,
        /// A swept parameter, `table.key=v1,v2,...` (repeatable), e.g. mpc_eso.rw=10,33,100.
        #[arg(long = "param")]
        params: Vec<String>,
        /// Noise seeds: `A..B` (B excluded) or `a,b,c` (default 0).
        #[arg(long, default_value = "0")]
        seeds: String,
        /// Where to write the CSV.
        #[arg(long)]
        out: PathBuf,
    },
    /// The paper's experiments: 4 scenarios x 4 controllers, the table against
    /// the paper, and a Markdown report with figures.
    Paper {
        /// Report directory.
        #[arg(long, default_value = "out/paper")]
        out: PathBuf,
        /// Preset: paper or fast.
        #[arg(long, default_value = "paper")]
        config: String,
        /// Also write every run's log into OUT/logs.
        #[arg(long)]
        logs: bool,
    },
    /// Simulate one scenario and write its run log (interfaces.md section 3).
    Run {
        /// What to simulate.
        #[command(flatten)]
        what: RunOpts,
        /// Noise seed (default 0).
        #[arg(long)]
        seed: Option<u64>,
        /// Plant step in seconds (default 1e-4; 2e-4 for the GRNN hose).
        #[arg(long)]
        dt: Option<f64>,
        /// Where to write the run log (CSV).
        #[arg(long)]
        log: PathBuf,
    },
    /// Print the MPC design (matrices and gains) of both MPC variants as JSON.
    Gains {
        /// Preset: paper or fast.
        #[arg(long, default_value = "paper")]
        config: String,
        /// Prediction horizon Np (both designs).
        #[arg(long)]
        np: Option<usize>,
        /// Control horizon Nc (both designs).
        #[arg(long)]
        nc: Option<usize>,
        /// MPC sample time Ts in seconds (both designs).
        #[arg(long)]
        ts: Option<f64>,
        /// Input weight r_w (both designs).
        #[arg(long)]
        rw: Option<f64>,
        /// Print JSON (the only format; accepted for the documented command line).
        #[arg(long)]
        json: bool,
        /// Pretty-print over several lines instead of one line.
        #[arg(long)]
        pretty: bool,
    },
}

fn parse_seeds(s: &str) -> Result<Vec<u64>, String> {
    let bad = || format!("--seeds '{s}': expected A..B or a,b,c");
    if let Some((a, b)) = s.split_once("..") {
        let (a, b): (u64, u64) = (
            a.trim().parse().map_err(|_| bad())?,
            b.trim().parse().map_err(|_| bad())?,
        );
        if b <= a || b - a > 100_000 {
            return Err(bad());
        }
        Ok((a..b).collect())
    } else {
        s.split(',')
            .map(|x| x.trim().parse().map_err(|_| bad()))
            .collect()
    }
}

/// A positive, finite number of seconds.
fn seconds(s: f64, what: &str) -> Result<std::time::Duration, String> {
    if s.is_finite() && s > 0.0 && s <= 3600.0 {
        Ok(std::time::Duration::from_secs_f64(s))
    } else {
        Err(format!("{what} {s}: expected seconds in (0, 3600]"))
    }
}

/// The emulated firmware's ELF: `elf`, or the default path, built if missing.
fn qemu_elf(elf: Option<PathBuf>) -> Result<PathBuf, String> {
    if let Some(e) = elf {
        return Ok(e);
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let path = root.join("target/qemu/thumbv7em-none-eabihf/firmware/dca-firmware");
    if !path.exists() {
        eprintln!("building the emulated firmware (cargo fw-qemu) ...");
        let status =
            std::process::Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
                .current_dir(&root)
                .args(["fw-qemu"])
                .status()
                .map_err(|e| format!("cargo fw-qemu: {e}"))?;
        if !status.success() {
            return Err(format!("cargo fw-qemu failed ({status}); install the target with `rustup target add thumbv7em-none-eabihf`"));
        }
    }
    Ok(path)
}

fn run(cli: Cli) -> Result<(), String> {
    match cli.command {
        Command::Hose {
            quasistatic,
            dynamic,
            out,
            memory,
            closed_loop,
        } => {
            use host_sim::grnn::{closed_loop as cl, data, memory as mem, paper};
            std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
            let qs = match &quasistatic {
                Some(p) => data::QuasiStaticData::load(p).map_err(|e| e.to_string())?,
                None => data::QuasiStaticData::shipped(),
            };
            let mut md = String::from("# Hose models (plant.md section 9)\n\n## GRNN, RBF and BP (80/20 split per section, the paper's Fig. 9)\n\n");
            let cmp = paper::compare_models(&qs, &paper::CompareOptions::default())
                .map_err(|e| e.to_string())?;
            let t = cmp.table();
            println!("{t}");
            md.push_str(&t);
            cmp.plot(&out.join("fig9_models.png"))?;
            md.push_str("\n![measured against predicted](fig9_models.png)\n");
            if memory {
                let dy = match &dynamic {
                    Some(p) => data::DynamicData::load(p).map_err(|e| e.to_string())?,
                    None => data::DynamicData::shipped(),
                };
                eprintln!("leave-one-run-out on the dynamic data ...");
                let rows = mem::leave_one_run_out(&dy, &qs, 4).map_err(|e| e.to_string())?;
                let t = mem::loro_table(&rows);
                println!("{t}");
                md.push_str("\n## GRNN with memory, held-out dynamic runs\n\n");
                md.push_str(&t);
            }
            if closed_loop {
                let rows = cl::stepload_comparison().map_err(|e| e.to_string())?;
                let t = cl::comparison_table(&rows);
                println!("{t}");
                md.push_str("\n## Closed loop: MPC-ESO, 800 N step\n\n");
                md.push_str(&t);
            }
            let report = out.join("report.md");
            std::fs::write(&report, md).map_err(|e| format!("{}: {e}", report.display()))?;
            eprintln!("report: {}", report.display());
            Ok(())
        }
        Command::GapSuite { out } => {
            use host_sim::gap::validation::{cases, markdown, run_suite};
            let t0 = std::time::Instant::now();
            let res = run_suite(&cases(), &Default::default(), true);
            let table = markdown(&res);
            println!("{table}");
            eprintln!(
                "{} cases in {:.1} s on {} threads",
                res.len(),
                t0.elapsed().as_secs_f64(),
                rayon::current_num_threads()
            );
            if let Some(p) = out {
                std::fs::write(&p, table).map_err(|e| format!("{}: {e}", p.display()))?;
            }
            Ok(())
        }
        Command::Hil {
            port,
            console,
            timeout,
            link_timeout_ms,
            qemu,
            elf,
            what,
            seed,
            compare,
            log,
        } => {
            use host_sim::hil;
            let spec = host_sim::run::resolve(&what.request(seed, None))?;
            let trace = match (port, qemu) {
                (Some(port), false) => {
                    if link_timeout_ms.is_some() && console.is_none() {
                        return Err("--link-timeout-ms needs --console (it is set there)".into());
                    }
                    let opts = hil::SerialOptions {
                        console,
                        timeout: seconds(timeout, "--timeout")?,
                        link_timeout_ms,
                        ..Default::default()
                    };
                    hil::run_hil_serial(&spec, &port, &opts).map_err(|e| e.to_string())?
                }
                (None, true) => {
                    let elf = qemu_elf(elf)?;
                    hil::run_hil_qemu(&spec, &elf, &hil::QemuOptions::default(), link_timeout_ms)
                        .map_err(|e| e.to_string())?
                }
                _ => {
                    return Err(
                        "give --port DEVICE (a board) or --qemu (the emulated firmware)".into(),
                    )
                }
            };
            let mut out =
                std::fs::File::create(&log).map_err(|e| format!("{}: {e}", log.display()))?;
            trace
                .write_log(&mut out)
                .map_err(|e| format!("{}: {e}", log.display()))?;
            eprintln!(
                "{} control ticks in the loop -> {}",
                trace.rows.len(),
                log.display()
            );
            if compare {
                let sw = hil::run_software(&spec).map_err(|e| e.to_string())?;
                match trace.first_difference(&sw) {
                    None => eprintln!(
                        "drive commands bit-identical to the software loop ({} ticks)",
                        sw.rows.len()
                    ),
                    Some(i) => {
                        return Err(format!(
                            "drive commands differ from the software loop first at tick {i}"
                        ))
                    }
                }
            }
            Ok(())
        }
        Command::Console {
            port,
            baud,
            qemu,
            elf,
            script,
            capture,
            timeout,
        } => {
            use host_sim::board::session::{parse_script, run_session, SessionOptions, Target};
            let script = match &script {
                Some(p) => {
                    let text =
                        std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()))?;
                    Some(parse_script(&text, &p.display().to_string())?)
                }
                None => None,
            };
            let target = match (port, qemu) {
                (Some(p), false) => Target::Port(p, baud),
                (None, true) => Target::Qemu(qemu_elf(elf)?, Default::default()),
                _ => return Err("give --port DEVICE (a board) or --qemu".into()),
            };
            let report = run_session(&SessionOptions {
                target,
                script,
                capture,
                timeout: seconds(timeout, "--timeout")?,
            })
            .map_err(|e| e.to_string())?;
            if let Some(p) = &report.capture_problem {
                return Err(p.clone());
            }
            if report.errors > 0 {
                return Err(format!(
                    "{} of {} replies were errors",
                    report.errors, report.sent
                ));
            }
            Ok(())
        }
        Command::Gap {
            fit,
            check,
            json,
            report,
        } => {
            let opts = host_sim::gap::diagnose::Options {
                progress: true,
                ..Default::default()
            };
            let d = host_sim::gap::run_gap(&fit, &check, &json, report.as_deref(), &opts)?;
            eprintln!(
                "verdict: {} (fit {:.2} -> {:.2}, check {:.2} -> {:.2}, {:.1} s) -> {}",
                d.verdict,
                d.fit.before,
                d.fit.after,
                d.check.before,
                d.check.after,
                d.elapsed_s,
                json.display()
            );
            Ok(())
        }
        Command::Bench { reps } => {
            print!("{}", host_sim::bench::table(&host_sim::bench::bench(reps)));
            Ok(())
        }
        Command::Sweep {
            what,
            params,
            seeds,
            out,
        } => {
            let params = params
                .iter()
                .map(|p| SweepParam::parse(p))
                .collect::<Result<Vec<_>, _>>()?;
            let seeds = parse_seeds(&seeds)?;
            let base = what.request(None, None);
            let t0 = std::time::Instant::now();
            let rows = sweep(&base, &params, &seeds, true)?;
            write_csv(&rows, &out)?;
            let failed = rows.iter().filter(|r| r.result.is_err()).count();
            eprintln!(
                "{} runs ({} failed) in {:.1} s on {} threads -> {}",
                rows.len(),
                failed,
                t0.elapsed().as_secs_f64(),
                rayon::current_num_threads(),
                out.display()
            );
            Ok(())
        }
        Command::Paper { out, config, logs } => {
            let preset = Preset::from_name(&config)
                .ok_or_else(|| format!("unknown --config '{config}': expected paper or fast"))?;
            let res = run_paper(&PaperOptions {
                out_dir: out,
                preset,
                write_logs: logs,
                progress: true,
            })?;
            println!("{}", table_markdown(&res.table));
            println!("report: {}", res.report.display());
            Ok(())
        }
        Command::Run {
            what,
            seed,
            dt,
            log,
        } => {
            let req = what.request(seed, dt);
            let (spec, trace) = execute(&req, &log)?;
            let m = trace_metrics(&trace, &spec.scenario);
            eprintln!(
                "{} / {} / {} hose / {} sensors: {} rows -> {}",
                spec.scenario.name(),
                trace.controller,
                spec.plant.hose_model().name(),
                spec.sensors.name(),
                trace.rows.len(),
                log.display()
            );
            println!("{}", serde_json::to_string(&m).map_err(|e| e.to_string())?);
            Ok(())
        }
        Command::Gains {
            config,
            np,
            nc,
            ts,
            rw,
            json: _,
            pretty,
        } => {
            let preset = Preset::from_name(&config)
                .ok_or_else(|| format!("unknown --config '{config}': expected paper or fast"))?;
            let v = gains(
                preset,
                &GainOverrides {
                    np,
                    nc,
                    ts_s: ts,
                    rw,
                },
            )?;
            let text = if pretty {
                serde_json::to_string_pretty(&v)
            } else {
                serde_json::to_string(&v)
            }
            .map_err(|e| e.to_string())?;
            println!("{text}");
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("host-sim: error: {e}");
            ExitCode::from(2)
        }
    }
}

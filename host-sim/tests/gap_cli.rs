//! `host-sim gap` as docs/interfaces.md section 2 fixes it: the JSON fields,
//! unusable logs rejected with the file, line and column named, and the
//! command line (the binary): its outputs optional, its runs' files checked.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use dca_core::controller::ControllerKind;
use dca_core::params::PlantParams;
use host_sim::gap::diagnose::Options;
use host_sim::gap::validation::{check_scenario, fit_scenario, rig_log};
use host_sim::gap::{run_gap, Outputs};
use host_sim::model::effects::{EffectKind, Effects};
use host_sim::sim::config::read_plant_file;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dca-gap-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn json_report_has_the_contract_fields() {
    let d = dir("json");
    let mut e = Effects::NONE;
    e.parse_arg("leakage:g_m3pspa=1e-13").unwrap();
    let fit = d.join("fit.csv");
    let check = d.join("check.csv");
    rig_log(fit_scenario(), ControllerKind::MpcEso, &e, 11)
        .write(&fit)
        .unwrap();
    rig_log(check_scenario(), ControllerKind::Pid, &e, 12)
        .write(&check)
        .unwrap();
    let json = d.join("report.json");
    let report = d.join("report");
    let rig_out = d.join("rig.toml");
    let diag = run_gap(
        &[fit],
        &[check],
        Outputs {
            json: Some(&json),
            report: Some(&report),
            rig_out: Some(&rig_out),
        },
        &Options::default(),
    )
    .unwrap();
    assert_eq!(diag.verdict, "leakage");
    // The identified rig: the verdict's effect with the fitted conductance,
    // read back by `--plant` bit for bit, nominal parameters.
    let rig = read_plant_file(&rig_out).unwrap();
    let g = rig
        .effects
        .leakage
        .expect("the leakage in the rig file")
        .g_m3pspa;
    assert_eq!(g, diag.candidates[0].params["g_m3pspa"], "{rig:?}");
    assert_eq!(rig.params, PlantParams::NOMINAL);
    assert_eq!(rig.effects.active(), [EffectKind::Leakage]);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for key in [
        "verdict",
        "gap_metric",
        "fit",
        "check",
        "candidates",
        "where",
    ] {
        assert!(!v[key].is_null(), "{key}");
    }
    for part in ["fit", "check"] {
        for key in ["before", "after", "shrink"] {
            assert!(v[part][key].is_number(), "{part}.{key}");
        }
    }
    let c = &v["candidates"][0];
    assert_eq!(c["effect"], "leakage");
    assert!(c["params"]["g_m3pspa"].as_f64().unwrap() > 0.0);
    assert!(c["fit_shrink"].is_number() && c["check_shrink"].is_number());
    // Where first: the isolation locates the leak between the lines before
    // any name, and the effects tried are those it allows and the best
    // closures name, each an identifier of docs/model.md section 12.
    let iso = &v["isolation"];
    assert_eq!(iso["names"], "leakage", "{iso}");
    assert!(iso["residuals"].as_array().unwrap().len() == 4);
    assert!(iso["closures"].as_array().unwrap().len() > 10);
    let all = v["candidates"].as_array().unwrap();
    assert!((1..=EffectKind::ALL.len()).contains(&all.len()));
    for c in all {
        let name = c["effect"].as_str().unwrap();
        assert!(EffectKind::ALL.iter().any(|k| k.name() == name), "{name}");
    }
    // The welcome fields: which form held, the subsystem, the re-estimate.
    assert_eq!(v["form"], "named");
    assert_eq!(v["subsystem"], "seals");
    assert!(v["parameters"].is_array());
    let w = &v["where"][0];
    for key in ["channel", "run", "t0_s", "t1_s", "label", "share"] {
        assert!(!w[key].is_null(), "where.{key}");
    }
    // Leakage shows while holding the load.
    assert_eq!(w["label"], "hold under load", "{w}");
    // The shrink is 1 - after / before.
    let f = &v["fit"];
    let s = 1.0 - f["after"].as_f64().unwrap() / f["before"].as_f64().unwrap();
    assert!((s - f["shrink"].as_f64().unwrap()).abs() < 1e-12);
    assert!(report.join("report.md").exists());
    assert!(report.join("residuals.png").exists());
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn bad_logs_name_file_line_and_column() {
    let d = dir("bad");
    let good = rig_log(fit_scenario(), ControllerKind::MpcEso, &Effects::NONE, 1);
    let mut text = Vec::new();
    good.write_to(&mut text).unwrap();
    let text = String::from_utf8(text).unwrap();
    let header_line = text.lines().position(|l| l.starts_with("t_s")).unwrap() + 1;
    let cases = [
        (
            "missing.csv",
            text.replacen("p2_pa", "p3_pa", 1),
            header_line,
            "p2_pa",
        ),
        (
            "nan.csv",
            {
                let mut lines: Vec<String> = text.lines().map(String::from).collect();
                let i = header_line + 20; // a data line
                let mut f: Vec<String> = lines[i - 1].split(',').map(String::from).collect();
                f[4] = "NaN".into();
                lines[i - 1] = f.join(",");
                lines.join("\n")
            },
            header_line + 20,
            "xo_m",
        ),
        (
            "gap.csv",
            {
                let mut lines: Vec<String> = text.lines().map(String::from).collect();
                lines.remove(header_line + 30);
                lines.join("\n")
            },
            header_line + 31,
            "t_s",
        ),
    ];
    let check = d.join("check.csv");
    std::fs::write(&check, &text).unwrap();
    for (name, body, line, column) in cases {
        let p = d.join(name);
        std::fs::write(&p, body).unwrap();
        let err = run_gap(
            std::slice::from_ref(&p),
            std::slice::from_ref(&check),
            Outputs {
                json: Some(&d.join("r.json")),
                ..Outputs::default()
            },
            &Options::default(),
        )
        .unwrap_err()
        .to_string();
        let want = format!("{}:{line}: column '{column}'", p.display());
        assert!(err.starts_with(&want), "{err}\nwant {want}");
    }
    let e = run_gap(&[], &[check], Outputs::default(), &Options::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("--fit"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

/// `host-sim gap ARGS` in `dir`.
fn host_sim_gap(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("gap")
        .args(args)
        .current_dir(dir)
        .output()
        .expect("host-sim runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// Two short clean runs (4 s each, 10 ms rows) as files `fit.csv` and
/// `check.csv`, the fit run with a byte-order mark as a spreadsheet writes
/// it; their text.
fn short_runs(d: &Path) -> (String, String) {
    let text = |scenario, kind, seed| {
        let log = rig_log(scenario, kind, &Effects::NONE, seed).decimate(10);
        let mut t = Vec::new();
        log.write_to(&mut t).unwrap();
        String::from_utf8(t).unwrap()
    };
    let fit = text(fit_scenario(), ControllerKind::MpcEso, 21);
    let check = text(check_scenario(), ControllerKind::Pid, 22);
    std::fs::write(d.join("fit.csv"), format!("\u{feff}{fit}")).unwrap();
    std::fs::write(d.join("check.csv"), &check).unwrap();
    (fit, check)
}

/// Without --json and --report the verdict and its numbers go to stdout;
/// --report alone writes the report and no JSON. (The fit run starts with
/// a byte-order mark.)
#[test]
fn the_outputs_are_optional() {
    let d = dir("outputs");
    short_runs(&d);
    let o = host_sim_gap(&d, &["--fit", "fit.csv", "--check", "check.csv"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.starts_with("verdict: "), "{out}");
    for want in [
        "fit   runs: gap ",
        "check runs: gap ",
        "best candidates",
        "reason: ",
    ] {
        assert!(out.contains(want), "{want}: {out}");
    }
    let o = host_sim_gap(
        &d,
        &[
            "--fit",
            "fit.csv",
            "--check",
            "check.csv",
            "--report",
            "rep",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stdout.is_empty());
    assert!(d.join("rep/report.md").exists());
    assert!(stderr(&o).contains("-> rep"), "{}", stderr(&o));
    assert!(!d.join("report.json").exists());
    std::fs::remove_dir_all(&d).ok();
}

/// Inputs refused before any diagnosis, each with the option, file, line,
/// column and range named: rows of 20 ms, a time column in milliseconds, a
/// step of 1e303 s (the last two once hung the replay), the same file as fit
/// and check run, a missing file.
#[test]
fn bad_runs_are_refused_at_once() {
    let d = dir("refused");
    let (fit, _) = short_runs(&d);
    let header = fit.lines().position(|l| l.starts_with("t_s")).unwrap() + 1;
    let retime = |f: &dyn Fn(f64) -> String| {
        let lines: Vec<String> = fit
            .lines()
            .map(|l| match l.split_once(',') {
                Some((t, rest)) if !l.starts_with("t_s") && !l.starts_with('#') => {
                    format!("{},{rest}", f(t.parse().unwrap()))
                }
                _ => l.to_string(),
            })
            .collect();
        lines.join("\n")
    };
    std::fs::write(d.join("ms.csv"), retime(&|t| format!("{}", t * 1000.0))).unwrap();
    std::fs::write(d.join("huge.csv"), retime(&|t| format!("{:e}", t * 1e305))).unwrap();
    // Every other row: 20 ms, as the console records at decimation 20.
    let mut data_row = 0;
    let twenty: Vec<&str> = fit
        .lines()
        .filter(|l| {
            l.starts_with('#') || l.starts_with("t_s") || {
                data_row += 1;
                data_row % 2 == 1
            }
        })
        .collect();
    std::fs::write(d.join("twenty.csv"), twenty.join("\n")).unwrap();
    let start = std::time::Instant::now();
    for (args, want) in [
        (
            ["--fit", "fit.csv", "--check", "twenty.csv"],
            format!(
                "host-sim: error: twenty.csv:{}: column 't_s': time step 0.02 s is outside \
                 0.0001 to 0.01 s, the range of the gap diagnosis (validated on rows of 1 to \
                 10 ms: at 20 ms a clean run's gap already reaches the verdict's threshold; \
                 1e-4 s is the plant's integration step)\n",
                header + 2
            ),
        ),
        (
            ["--fit", "ms.csv", "--check", "check.csv"],
            format!(
                "host-sim: error: ms.csv:{}: column 't_s': time step 10 s is outside 0.0001 \
                 to 0.01 s, the range of the gap diagnosis (validated on rows of 1 to 10 ms: \
                 at 20 ms a clean run's gap already reaches the verdict's threshold; 1e-4 s \
                 is the plant's integration step); t_s is in seconds: if this column is in \
                 milliseconds, divide it by 1000 (a step of 0.01 s)\n",
                header + 2
            ),
        ),
        (
            ["--fit", "huge.csv", "--check", "check.csv"],
            format!(
                "host-sim: error: huge.csv:{}: column 't_s': time step 1e303 s is outside \
                 0.0001 to 0.01 s, the range of the gap diagnosis (validated on rows of 1 to \
                 10 ms: at 20 ms a clean run's gap already reaches the verdict's threshold; \
                 1e-4 s is the plant's integration step)\n",
                header + 2
            ),
        ),
        (
            ["--fit", "fit.csv", "--check", "./fit.csv"],
            "host-sim: error: --check ./fit.csv is the same file as --fit fit.csv: a check \
             run must be held out from the fit (give another recorded run)\n"
                .to_string(),
        ),
        (
            ["--fit", "out/a.csv", "--check", "check.csv"],
            "host-sim: error: --fit out/a.csv: no such file\n".to_string(),
        ),
        (
            ["--fit", "fit.csv", "--check", "nope.csv"],
            "host-sim: error: --check nope.csv: no such file\n".to_string(),
        ),
    ] {
        let o = host_sim_gap(&d, &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert_eq!(stderr(&o), want, "{args:?}");
    }
    // Refused while reading: no diagnosis ran.
    assert!(start.elapsed().as_secs() < 20, "{:?}", start.elapsed());
    std::fs::remove_dir_all(&d).ok();
}

/// A clean rig under `cmpc-eso` `limit`, whose command moves at every tick,
/// captured at 10 ms as the console records it: the replay infers what the
/// nine unrecorded commands of each row did from the encoder, within their
/// bound, and the verdict is `none` (with the recorded commands held over
/// their rows the fit runs' gap was 114).
#[test]
fn a_clean_rig_under_a_busy_controller_is_none_at_10_ms() {
    let d = dir("busy");
    for (name, scenario, controller, config, seed) in [
        ("fit", "stepload", "cmpc-eso", "limit", "1"),
        ("check", "sineload", "mpc-eso", "paper", "2"),
    ] {
        let full = d.join(format!("{name}-1ms.csv"));
        let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(["run", "--scenario", scenario, "--controller", controller])
            .args(["--config", config, "--sensors", "realistic", "--seed", seed])
            .arg("--log")
            .arg(&full)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        let log = host_sim::io::runlog::RunLog::read(&full).unwrap();
        log.decimate(10)
            .write(&d.join(format!("{name}.csv")))
            .unwrap();
    }
    let out = host_sim_gap(
        &d,
        &[
            "--fit",
            "fit.csv",
            "--check",
            "check.csv",
            "--json",
            "g.json",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("g.json")).unwrap()).unwrap();
    let fit = v["fit"]["before"].as_f64().unwrap();
    assert_eq!(v["verdict"], "none", "fit gap {fit}");
    assert!(fit < 1.0, "fit gap {fit}");
    std::fs::remove_dir_all(&d).unwrap();
}

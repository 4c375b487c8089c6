//! `host-sim gap` as docs/interfaces.md section 2 fixes it: the JSON fields, and
//! unusable logs rejected with the file, line and column named.

use std::path::PathBuf;

use dca_core::controller::ControllerKind;
use host_sim::gap::diagnose::Options;
use host_sim::gap::run_gap;
use host_sim::gap::validation::{check_scenario, fit_scenario, rig_log};
use host_sim::model::effects::{EffectKind, Effects};

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
    let diag = run_gap(&[fit], &[check], &json, Some(&report), &Options::default()).unwrap();
    assert_eq!(diag.verdict, "leakage");
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
    // Every effect of docs/model.md section 12 is tried, the two outside
    // the catalogue included.
    let all = v["candidates"].as_array().unwrap();
    assert_eq!(all.len(), EffectKind::ALL.len());
    for k in ["sensor_calibration", "parameters"] {
        assert!(all.iter().any(|c| c["effect"] == k), "{k} tried");
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
            &d.join("r.json"),
            None,
            &Options::default(),
        )
        .unwrap_err()
        .to_string();
        let want = format!("{}:{line}: column '{column}'", p.display());
        assert!(err.starts_with(&want), "{err}\nwant {want}");
    }
    let e = run_gap(&[], &[check], &d.join("r.json"), None, &Options::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("--fit"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

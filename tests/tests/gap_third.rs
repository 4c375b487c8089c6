//! The third family of rigs (tests/src/third, docs/gap-validation.md).
//!
//! * `plant_matches_the_specification_vectors` (fast): this family's own plant
//!   against the unit-test vector of docs/model.md section 4.2 and the rest state
//!   of section 4.1.
//! * `gap_third_confusion` (ignored, a measurement of several minutes): every
//!   case's fit and check logs, `host-sim gap` on them at 1 ms and decimated to
//!   10 ms rows, and the confusion tables in target/gap-third.md. It fails only
//!   when a diagnosis errors or its JSON has no verdict.

use dca_tests::third::plant::{Rig, N_STATES};

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-300)
}

#[test]
fn plant_matches_the_specification_vectors() {
    let rig = Rig::nominal();
    let p = &rig.params;
    // Section 4.1, Ft(0) = 0.
    let x = rig.rest(0.0);
    let (v1, v2) = p.volumes_m3(0.0, 0.0);
    let want = [
        (x[4], 640_127.388535, "P1"),
        (v1, 7.588433388e-5, "V1"),
        (v2, 5.829433388e-5, "V2"),
        (x[6], 5.93728698e-8, "Vf1"),
        (x[7], 2.37491479e-7, "Vs1"),
        (x[8], 8.31776617e-8, "Vf2"),
        (x[9], 3.32710647e-7, "Vs2"),
    ];
    for (got, w, name) in want {
        assert!(close(got, w, 1e-9), "rest {name}: {got} against {w}");
    }
    assert!(close(rig.rest(400.0)[4], 1_914_012.74, 1e-8));
    // The rest state is an equilibrium of the nominal plant.
    let d = rig.rhs(0.0, &x, 0.0, 0.0);
    for (i, v) in d.iter().enumerate() {
        assert!(v.abs() < 1e-6, "rest derivative {i}: {v}");
    }

    // Section 4.2.
    let mut s = [0.0; N_STATES];
    s[..11].copy_from_slice(&[
        0.02, 0.03, 0.025, 0.035, 1.5e6, 0.9e6, 1.0e-7, 3.0e-7, 8.0e-8, 3.2e-7, 1.02e-4,
    ]);
    let dx = rig.rhs(0.0, &s, 0.05, 300.0);
    let want_dx = [
        3.0e-2,
        2.0,
        3.5e-2,
        -3.38e-1,
        -1.0238585629e+07,
        2.3835811180e+08,
        9.9548878249e-07,
        4.6606517100e-07,
        -2.9775336593e-07,
        -3.9700448791e-08,
        3.4943288135e-05,
    ];
    for i in 0..11 {
        assert!(
            close(dx[i], want_dx[i], 1e-9),
            "dx[{i}]: {} against {}",
            dx[i],
            want_dx[i]
        );
    }
    assert!(close(p.p_acc_pa(1.02e-4), 9.6988657627e+05, 1e-9));
    let (v1, v2) = p.volumes_m3(0.02, 0.025);
    assert!(close(v1, 7.6194333882e-05, 1e-9) && close(v2, 6.3089333882e-05, 1e-9));
    rig.step(0.0, &mut s, 0.05, 300.0, 1e-4);
    let want_x = [
        2.000300996675e-02,
        3.019900332500e-02,
        2.500349815754e-02,
        3.496172755503e-02,
        1.499022048527e+06,
        9.192888336962e+05,
        1.000988151729e-07,
        3.000465669651e-07,
        7.997687567055e-08,
        3.199969004970e-07,
        1.020029747755e-04,
    ];
    for i in 0..11 {
        assert!(
            close(s[i], want_x[i], 1e-9),
            "x[{i}]: {} against {}",
            s[i],
            want_x[i]
        );
    }
}

// ---------------------------------------------------------------------------
// The measurement run.

mod json {
    //! A minimal JSON reader (objects, arrays, strings, numbers, literals),
    //! enough to read the report of docs/interfaces.md section 2 without a
    //! dependency.

    /// A JSON value.
    #[derive(Clone, Debug, PartialEq)]
    pub enum Value {
        Null,
        Bool(bool),
        Num(f64),
        Str(String),
        Arr(Vec<Value>),
        Obj(Vec<(String, Value)>),
    }

    impl Value {
        /// Member `key` of an object.
        pub fn get(&self, key: &str) -> Option<&Value> {
            match self {
                Value::Obj(m) => m.iter().find(|(k, _)| k == key).map(|(_, v)| v),
                _ => None,
            }
        }
        /// The number, if this is one.
        pub fn num(&self) -> Option<f64> {
            match self {
                Value::Num(x) => Some(*x),
                _ => None,
            }
        }
        /// The string, if this is one.
        pub fn str(&self) -> Option<&str> {
            match self {
                Value::Str(s) => Some(s),
                _ => None,
            }
        }
    }

    /// Parse a whole document.
    pub fn parse(text: &str) -> Result<Value, String> {
        let b: Vec<char> = text.chars().collect();
        let mut i = 0;
        let v = value(&b, &mut i)?;
        ws(&b, &mut i);
        if i != b.len() {
            return Err(format!("trailing text at {i}"));
        }
        Ok(v)
    }

    fn ws(b: &[char], i: &mut usize) {
        while *i < b.len() && b[*i].is_whitespace() {
            *i += 1;
        }
    }

    fn value(b: &[char], i: &mut usize) -> Result<Value, String> {
        ws(b, i);
        match b.get(*i) {
            None => Err("unexpected end".into()),
            Some('{') => {
                *i += 1;
                let mut m = Vec::new();
                ws(b, i);
                if b.get(*i) == Some(&'}') {
                    *i += 1;
                    return Ok(Value::Obj(m));
                }
                loop {
                    ws(b, i);
                    let Value::Str(k) = string(b, i)? else {
                        unreachable!()
                    };
                    ws(b, i);
                    if b.get(*i) != Some(&':') {
                        return Err(format!("':' expected at {i}"));
                    }
                    *i += 1;
                    m.push((k, value(b, i)?));
                    ws(b, i);
                    match b.get(*i) {
                        Some(',') => *i += 1,
                        Some('}') => {
                            *i += 1;
                            return Ok(Value::Obj(m));
                        }
                        _ => return Err(format!("',' or '}}' expected at {i}")),
                    }
                }
            }
            Some('[') => {
                *i += 1;
                let mut a = Vec::new();
                ws(b, i);
                if b.get(*i) == Some(&']') {
                    *i += 1;
                    return Ok(Value::Arr(a));
                }
                loop {
                    a.push(value(b, i)?);
                    ws(b, i);
                    match b.get(*i) {
                        Some(',') => *i += 1,
                        Some(']') => {
                            *i += 1;
                            return Ok(Value::Arr(a));
                        }
                        _ => return Err(format!("',' or ']' expected at {i}")),
                    }
                }
            }
            Some('"') => string(b, i),
            Some('t') => lit(b, i, "true", Value::Bool(true)),
            Some('f') => lit(b, i, "false", Value::Bool(false)),
            Some('n') => lit(b, i, "null", Value::Null),
            Some(_) => {
                let s = *i;
                while *i < b.len() && "+-0123456789.eE".contains(b[*i]) {
                    *i += 1;
                }
                let t: String = b[s..*i].iter().collect();
                t.parse()
                    .map(Value::Num)
                    .map_err(|_| format!("bad number '{t}' at {s}"))
            }
        }
    }

    fn lit(b: &[char], i: &mut usize, word: &str, v: Value) -> Result<Value, String> {
        let n = word.chars().count();
        if b.len() >= *i + n && b[*i..*i + n].iter().copied().eq(word.chars()) {
            *i += n;
            Ok(v)
        } else {
            Err(format!("bad literal at {i}"))
        }
    }

    fn string(b: &[char], i: &mut usize) -> Result<Value, String> {
        if b.get(*i) != Some(&'"') {
            return Err(format!("string expected at {i}"));
        }
        *i += 1;
        let mut s = String::new();
        while let Some(&c) = b.get(*i) {
            *i += 1;
            match c {
                '"' => return Ok(Value::Str(s)),
                '\\' => {
                    let e = *b.get(*i).ok_or("bad escape")?;
                    *i += 1;
                    match e {
                        'n' => s.push('\n'),
                        't' => s.push('\t'),
                        'r' => s.push('\r'),
                        'b' => s.push('\u{8}'),
                        'f' => s.push('\u{c}'),
                        'u' => {
                            let h: String = b.get(*i..*i + 4).ok_or("bad \\u")?.iter().collect();
                            *i += 4;
                            let cp = u32::from_str_radix(&h, 16).map_err(|_| "bad \\u")?;
                            s.push(char::from_u32(cp).unwrap_or('\u{fffd}'));
                        }
                        other => s.push(other),
                    }
                }
                c => s.push(c),
            }
        }
        Err("unterminated string".into())
    }
}

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use dca_tests::third::cases::{self, Case, Kind};
use dca_tests::third::scenario::{run, Scenario};

/// target/ of this build (the test binary lives in target/<profile>/deps/).
fn target_profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    exe.parent()
        .and_then(Path::parent)
        .expect("target/<profile>/deps")
        .to_path_buf()
}

/// The `host-sim` binary of the same profile, brought up to date first (a
/// binary left from an older build would measure older code: cargo does not
/// rebuild it for this test, which does not depend on the binary target).
fn host_sim_bin(profile_dir: &Path) -> PathBuf {
    let bin = profile_dir.join(format!("host-sim{}", std::env::consts::EXE_SUFFIX));
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.args(["build", "-p", "host-sim", "--bin", "host-sim"]);
    if profile_dir.file_name().and_then(|s| s.to_str()) == Some("release") {
        cmd.arg("--release");
    }
    let st = cmd.status().expect("cargo build host-sim");
    assert!(st.success(), "building host-sim failed");
    bin
}

/// One diagnosis as read from its JSON report.
#[derive(Clone, Debug)]
struct Outcome {
    verdict: String,
    form: Option<String>,
    fit: [f64; 3],
    check: [f64; 3],
    elapsed_s: f64,
}

fn triple(v: &json::Value, key: &str) -> [f64; 3] {
    let part = v.get(key);
    let n = |k: &str| {
        part.and_then(|p| p.get(k))
            .and_then(json::Value::num)
            .unwrap_or(f64::NAN)
    };
    [n("before"), n("after"), n("shrink")]
}

fn diagnose(bin: &Path, dir: &Path, suffix: &str) -> Result<Outcome, String> {
    let json_path = dir.join(format!("report{suffix}.json"));
    let _ = std::fs::remove_file(&json_path);
    let t0 = Instant::now();
    let out = Command::new(bin)
        .arg("gap")
        .arg("--fit")
        .arg(dir.join(format!("fit{suffix}.csv")))
        .arg("--check")
        .arg(dir.join(format!("check{suffix}.csv")))
        .arg("--json")
        .arg(&json_path)
        .output()
        .map_err(|e| format!("cannot start {}: {e}", bin.display()))?;
    let elapsed_s = t0.elapsed().as_secs_f64();
    if !out.status.success() {
        return Err(format!(
            "host-sim gap failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    let text =
        std::fs::read_to_string(&json_path).map_err(|e| format!("{}: {e}", json_path.display()))?;
    let v = json::parse(&text).map_err(|e| format!("{}: {e}", json_path.display()))?;
    let verdict = v
        .get("verdict")
        .and_then(json::Value::str)
        .ok_or_else(|| format!("{}: no verdict", json_path.display()))?
        .to_string();
    let form = v.get("form").and_then(|f| match f {
        json::Value::Str(s) => Some(s.clone()),
        json::Value::Null => None,
        other => Some(format!("{other:?}")),
    });
    Ok(Outcome {
        verdict,
        form,
        fit: triple(&v, "fit"),
        check: triple(&v, "check"),
        elapsed_s,
    })
}

fn is_right(c: &Case, verdict: &str) -> bool {
    c.truth.contains(&verdict)
}

fn truth_label(c: &Case) -> String {
    match c.kind {
        Kind::Pair => format!("pair {}", c.truth.join(" + ")),
        Kind::Outside => "unexplained (outside)".to_string(),
        _ => c.truth[0].to_string(),
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Markdown for one resolution: confusion table, counts, per-case lines.
fn tables(title: &str, cases: &[Case], res: &[Outcome]) -> String {
    let mut s = format!("### {title}\n\n");
    // Columns: every verdict that occurred, truth identifiers first.
    let mut cols: Vec<String> = Vec::new();
    for c in cases {
        for t in &c.truth {
            if !cols.iter().any(|x| x == t) {
                cols.push(t.to_string());
            }
        }
    }
    for r in res {
        if !cols.contains(&r.verdict) {
            cols.push(r.verdict.clone());
        }
    }
    let mut rows: Vec<String> = Vec::new();
    for c in cases {
        let l = truth_label(c);
        if !rows.contains(&l) {
            rows.push(l);
        }
    }
    s.push_str("| truth \\ verdict |");
    for c in &cols {
        s.push_str(&format!(" {c} |"));
    }
    s.push_str("\n|---|");
    for _ in &cols {
        s.push_str("---|");
    }
    s.push('\n');
    for row in &rows {
        s.push_str(&format!("| {row} |"));
        for col in &cols {
            let n = cases
                .iter()
                .zip(res)
                .filter(|(c, r)| truth_label(c) == *row && r.verdict == *col)
                .count();
            if n == 0 {
                s.push_str(" . |");
            } else {
                s.push_str(&format!(" {n} |"));
            }
        }
        s.push('\n');
    }
    let count = |k: Kind| {
        let sel: Vec<_> = cases.iter().zip(res).filter(|(c, _)| c.kind == k).collect();
        let right = sel.iter().filter(|(c, r)| is_right(c, &r.verdict)).count();
        (right, sel.len())
    };
    let (s1, n1) = count(Kind::Single);
    let (s2, n2) = count(Kind::Clean);
    let (s3, n3) = count(Kind::Outside);
    let (s4, n4) = count(Kind::Pair);
    let shrink_single = median(
        cases
            .iter()
            .zip(res)
            .filter(|(c, _)| c.kind == Kind::Single)
            .map(|(_, r)| r.check[2])
            .collect(),
    );
    let shrink_all = median(
        cases
            .iter()
            .zip(res)
            .filter(|(c, _)| matches!(c.kind, Kind::Single | Kind::Pair))
            .map(|(_, r)| r.check[2])
            .collect(),
    );
    let elapsed: Vec<f64> = res.iter().map(|r| r.elapsed_s).collect();
    let total: f64 = elapsed.iter().sum();
    s.push_str(&format!(
        "\nSingle effects right: {s1}/{n1} ({:.0} %). Clean runs `none`: {s2}/{n2}. \
         Outside the catalogue `unexplained`: {s3}/{n3}. Pairs (either effect named): {s4}/{n4}. \
         All: {}/{}.\n\
         Median check shrink: {shrink_single:.2} over the single effects, {shrink_all:.2} over \
         single effects and pairs. Diagnosis time: median {:.1} s, longest {:.1} s, total {:.0} s.\n\n",
        100.0 * s1 as f64 / n1.max(1) as f64,
        s1 + s2 + s3 + s4,
        n1 + n2 + n3 + n4,
        median(elapsed.clone()),
        elapsed.iter().cloned().fold(0.0, f64::max),
        total,
    ));
    s.push_str(
        "| case | truth | verdict | right | form | fit before | fit after | fit shrink | check before | check after | check shrink | time [s] |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for (c, r) in cases.iter().zip(res) {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} |\n",
            c.name,
            c.truth.join(" or "),
            r.verdict,
            if is_right(c, &r.verdict) { "yes" } else { "no" },
            r.form.as_deref().unwrap_or("-"),
            r.fit[0],
            r.fit[1],
            r.fit[2],
            r.check[0],
            r.check[1],
            r.check[2],
            r.elapsed_s
        ));
    }
    s.push('\n');
    s
}

fn git_commit() -> String {
    Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown".into())
}

fn today() -> String {
    Command::new("date")
        .args(["-u", "+%Y-%m-%d %H:%M UTC"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown date".into())
}

#[test]
#[ignore = "measurement run: 28 cases x 2 resolutions of host-sim gap, several minutes in release"]
fn gap_third_confusion() {
    let profile_dir = target_profile_dir();
    let target = profile_dir.parent().expect("target dir").to_path_buf();
    let root = target.join("gap-third");
    let bin = host_sim_bin(&profile_dir);
    let only = std::env::var("GAP_THIRD_ONLY").ok();
    let cases: Vec<Case> = cases::all()
        .into_iter()
        .filter(|c| {
            only.as_deref()
                .is_none_or(|o| o.split(',').any(|n| n == c.name))
        })
        .collect();
    let t_start = Instant::now();

    // Logs: fit and check per case, at 1 ms and decimated to 10 ms rows.
    for (i, c) in cases::all().iter().enumerate() {
        if !cases.iter().any(|x| x.name == c.name) {
            continue;
        }
        let dir = root.join(c.name);
        std::fs::create_dir_all(&dir).unwrap();
        let fit = run(&c.rig, Scenario::Fit, 7001 + 17 * i as u64)
            .unwrap_or_else(|e| panic!("{}: fit run: {e}", c.name));
        let check = run(&c.rig, Scenario::Check, 9103 + 17 * i as u64)
            .unwrap_or_else(|e| panic!("{}: check run: {e}", c.name));
        fit.write(&dir.join("fit.csv")).unwrap();
        check.write(&dir.join("check.csv")).unwrap();
        fit.decimate(10).write(&dir.join("fit10.csv")).unwrap();
        check.decimate(10).write(&dir.join("check10.csv")).unwrap();
    }
    let t_logs = t_start.elapsed().as_secs_f64();

    let mut md = format!(
        "# Gap diagnosis on the third family\n\nMeasured {} on commit {}, {} cases; \
         logs generated in {t_logs:.0} s.\n\n",
        today(),
        git_commit(),
        cases.len()
    );
    let mut failures = Vec::new();
    for (suffix, title) in [("", "1 ms logs"), ("10", "10 ms logs (every 10th row)")] {
        let mut res = Vec::new();
        for c in &cases {
            let o = match diagnose(&bin, &root.join(c.name), suffix) {
                Ok(o) => o,
                Err(e) => {
                    failures.push(format!("{} ({title}): {e}", c.name));
                    Outcome {
                        verdict: "ERROR".into(),
                        form: None,
                        fit: [f64::NAN; 3],
                        check: [f64::NAN; 3],
                        elapsed_s: f64::NAN,
                    }
                }
            };
            println!(
                "{title}: {:<22} truth {:<28} verdict {:<20} check {:.2} -> {:.2} ({:.2}) {:.1} s",
                c.name,
                c.truth.join("|"),
                o.verdict,
                o.check[0],
                o.check[1],
                o.check[2],
                o.elapsed_s
            );
            res.push(o);
        }
        md.push_str(&tables(title, &cases, &res));
    }
    md.push_str(&format!(
        "Total run time {:.0} s.\n",
        t_start.elapsed().as_secs_f64()
    ));
    let out = target.join("gap-third.md");
    std::fs::write(&out, &md).unwrap();
    println!("\n{md}\nwritten to {}", out.display());
    assert!(
        failures.is_empty(),
        "diagnoses failed:\n{}",
        failures.join("\n")
    );
}

//! The measurement run shared by the families' gap tests
//! (tests/tests/gap_fourth.rs, tests/tests/gap_fifth.rs): every case's fit
//! and check logs in `target/gap-<family>/<case>/`, the release `host-sim gap`
//! on them at 1 ms and decimated to 10 ms rows, and the tables in
//! `target/gap-<family>.md`.

use super::cases::{self, Case, Kind};
use super::scenario::{run, Log};

/// A family of rigs to measure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Family {
    /// Its name (`fourth`): `target/gap-<name>/` and `target/gap-<name>.md`.
    pub name: &'static str,
    /// The source files named in the report.
    pub sources: &'static str,
}

mod json {
    //! A small JSON reader, enough for the report of interfaces.md section 2.

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

        /// A compact one-line rendering for the report.
        pub fn short(&self) -> String {
            match self {
                Value::Null => "-".into(),
                Value::Bool(b) => b.to_string(),
                Value::Num(x) => format!("{x}"),
                Value::Str(s) => s.clone(),
                Value::Arr(a) => a.iter().map(Value::short).collect::<Vec<_>>().join(", "),
                Value::Obj(m) => m
                    .iter()
                    .map(|(k, v)| format!("{k}: {}", v.short()))
                    .collect::<Vec<_>>()
                    .join("; "),
            }
        }
    }

    /// Parse a whole document.
    pub fn parse(text: &str) -> Result<Value, String> {
        let b: Vec<char> = text.chars().collect();
        let mut i = 0;
        let v = value(&b, &mut i)?;
        skip_ws(&b, &mut i);
        if i != b.len() {
            return Err(format!("trailing text at {i}"));
        }
        Ok(v)
    }

    fn skip_ws(b: &[char], i: &mut usize) {
        while *i < b.len() && b[*i].is_whitespace() {
            *i += 1;
        }
    }

    fn expect(b: &[char], i: &mut usize, c: char) -> Result<(), String> {
        skip_ws(b, i);
        if b.get(*i) == Some(&c) {
            *i += 1;
            Ok(())
        } else {
            Err(format!("'{c}' expected at {i}"))
        }
    }

    fn value(b: &[char], i: &mut usize) -> Result<Value, String> {
        skip_ws(b, i);
        match b.get(*i) {
            None => Err("unexpected end".into()),
            Some('{') => {
                *i += 1;
                let mut m = Vec::new();
                skip_ws(b, i);
                if b.get(*i) == Some(&'}') {
                    *i += 1;
                    return Ok(Value::Obj(m));
                }
                loop {
                    skip_ws(b, i);
                    let k = string(b, i)?;
                    expect(b, i, ':')?;
                    m.push((k, value(b, i)?));
                    skip_ws(b, i);
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
                skip_ws(b, i);
                if b.get(*i) == Some(&']') {
                    *i += 1;
                    return Ok(Value::Arr(a));
                }
                loop {
                    a.push(value(b, i)?);
                    skip_ws(b, i);
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
            Some('"') => string(b, i).map(Value::Str),
            Some('t') => literal(b, i, "true", Value::Bool(true)),
            Some('f') => literal(b, i, "false", Value::Bool(false)),
            Some('n') => literal(b, i, "null", Value::Null),
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

    fn literal(b: &[char], i: &mut usize, word: &str, v: Value) -> Result<Value, String> {
        let n = word.chars().count();
        if b.len() >= *i + n && b[*i..*i + n].iter().copied().eq(word.chars()) {
            *i += n;
            Ok(v)
        } else {
            Err(format!("bad literal at {i}"))
        }
    }

    fn string(b: &[char], i: &mut usize) -> Result<String, String> {
        if b.get(*i) != Some(&'"') {
            return Err(format!("string expected at {i}"));
        }
        *i += 1;
        let mut s = String::new();
        while let Some(&c) = b.get(*i) {
            *i += 1;
            match c {
                '"' => return Ok(s),
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
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// The identifiers of plant.md section 12, then `none` and `unexplained`.
const VOCABULARY: [&str; 12] = [
    "leakage",
    "friction",
    "backlash",
    "air",
    "sensor_delay",
    "motor_limit",
    "hose_hysteresis",
    "accumulator_thermal",
    "sensor_calibration",
    "parameters",
    "none",
    "unexplained",
];

/// The two log resolutions: file suffix, rows kept (every n-th), title.
const RESOLUTIONS: [(&str, usize, &str); 2] = [("", 1, "1 ms"), ("-10ms", 10, "10 ms")];

/// target/ of this build (the test binary lives in target/<profile>/deps/).
fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    exe.parent()
        .and_then(Path::parent)
        .and_then(Path::parent)
        .expect("target/<profile>/deps")
        .to_path_buf()
}

/// The release `host-sim` binary, brought up to date first (cargo does not
/// rebuild it for this test, which does not depend on the binary target).
fn host_sim_release(target: &Path) -> PathBuf {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let st = Command::new(cargo)
        .args(["build", "--release", "-p", "host-sim", "--bin", "host-sim"])
        .status()
        .expect("cargo build host-sim");
    assert!(st.success(), "building host-sim failed");
    target
        .join("release")
        .join(format!("host-sim{}", std::env::consts::EXE_SUFFIX))
}

/// One diagnosis as read from its JSON report.
#[derive(Clone, Debug)]
struct Outcome {
    verdict: String,
    check_shrink: f64,
    equation: String,
    names: String,
    seconds: f64,
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
    let seconds = t0.elapsed().as_secs_f64();
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
    let check_shrink = v
        .get("check")
        .and_then(|c| c.get("shrink"))
        .and_then(json::Value::num)
        .unwrap_or(f64::NAN);
    let iso = v.get("isolation");
    let field = |k: &str| {
        iso.and_then(|o| o.get(k))
            .map(json::Value::short)
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| "-".into())
    };
    Ok(Outcome {
        verdict,
        check_shrink,
        equation: field("equation"),
        names: field("names"),
        seconds,
    })
}

fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Per case: the truth as printed, and for a pair the larger member.
struct Truth {
    label: String,
    larger: Option<&'static str>,
    visibility: f64,
}

fn truth_of(c: &Case, vis: &[f64]) -> Truth {
    let larger = (c.kind == Kind::Pair).then(|| {
        if vis[1] >= vis[2] {
            c.truth[0]
        } else {
            c.truth[1]
        }
    });
    let label = match larger {
        Some(l) => {
            let other = c.truth.iter().find(|t| **t != l).copied().unwrap_or("?");
            format!("{l}>{other}")
        }
        None => c.expected(),
    };
    Truth {
        label,
        larger,
        visibility: vis[0],
    }
}

fn tables(
    title: &str,
    cases: &[Case],
    truths: &[Truth],
    res: &[Result<Outcome, String>],
) -> String {
    let verdicts: Vec<String> = res
        .iter()
        .map(|r| match r {
            Ok(o) => o.verdict.clone(),
            Err(_) => "error".to_string(),
        })
        .collect();
    let mut s = format!("## {title}\n\n");
    s.push_str(&confusion(cases, truths, &verdicts));
    s.push_str(&counts(cases, truths, &verdicts, res));
    s.push_str(&per_case(cases, truths, res));
    s.push('\n');
    s
}

/// The confusion table: rows the truths, columns the verdicts.
fn confusion(cases: &[Case], truths: &[Truth], verdicts: &[String]) -> String {
    let mut s = String::new();
    let mut rows: Vec<String> = Vec::new();
    for t in truths {
        if !rows.contains(&t.label) {
            rows.push(t.label.clone());
        }
    }
    let mut cols: Vec<String> = VOCABULARY.iter().map(|v| v.to_string()).collect();
    for v in verdicts {
        if !cols.contains(v) {
            cols.push(v.clone());
        }
    }
    let short = |c: &str| -> String {
        match c {
            "accumulator_thermal" => "acc_th".into(),
            "sensor_calibration" => "sens_cal".into(),
            "sensor_delay" => "sens_del".into(),
            "hose_hysteresis" => "hose_hys".into(),
            "motor_limit" => "motor".into(),
            "unexplained" => "unexpl".into(),
            "parameters" => "params".into(),
            other => other.into(),
        }
    };
    s.push_str("Confusion (rows: truth, columns: verdict; a pair's larger effect first):\n\n");
    s.push_str("| truth |");
    for c in &cols {
        s.push_str(&format!(" {} |", short(c)));
    }
    s.push_str("\n|---|");
    for _ in &cols {
        s.push_str("---|");
    }
    s.push('\n');
    for r in &rows {
        s.push_str(&format!("| {r} |"));
        for c in &cols {
            let n = (0..cases.len())
                .filter(|&i| &truths[i].label == r && &verdicts[i] == c)
                .count();
            if n == 0 {
                s.push_str(" . |");
            } else {
                s.push_str(&format!(" {n} |"));
            }
        }
        s.push('\n');
    }
    s
}

/// Counts of right verdicts per kind, wrong effects, the median check shrink
/// and the summed time.
fn counts(
    cases: &[Case],
    truths: &[Truth],
    verdicts: &[String],
    res: &[Result<Outcome, String>],
) -> String {
    let mut s = String::new();
    s.push_str("\nCounts per kind:\n\n");
    for kind in [
        Kind::Single,
        Kind::Weak,
        Kind::Pair,
        Kind::Clean,
        Kind::Outside,
    ] {
        let idx: Vec<usize> = (0..cases.len())
            .filter(|&i| cases[i].kind == kind)
            .collect();
        let right = idx
            .iter()
            .filter(|&&i| cases[i].is_right(&verdicts[i]))
            .count();
        let what = match kind {
            Kind::Single | Kind::Weak => "named the effect",
            Kind::Pair => "named one of the two",
            Kind::Clean => "`none`",
            Kind::Outside => "`unexplained`",
        };
        s.push_str(&format!("* {}: {right}/{} {what}", kind.name(), idx.len()));
        if kind == Kind::Pair {
            let larger = idx
                .iter()
                .filter(|&&i| truths[i].larger == Some(verdicts[i].as_str()))
                .count();
            s.push_str(&format!(", {larger}/{} named the larger", idx.len()));
        }
        s.push('\n');
    }
    let right_total = (0..cases.len())
        .filter(|&i| cases[i].is_right(&verdicts[i]))
        .count();
    s.push_str(&format!("* all: {right_total}/{} right\n", cases.len()));
    // Wrong effects.
    let wrong: Vec<String> = (0..cases.len())
        .filter(|&i| {
            let v = &verdicts[i];
            VOCABULARY[..10].contains(&v.as_str()) && !cases[i].truth.contains(&v.as_str())
        })
        .map(|i| format!("{} ({} -> {})", cases[i].id, truths[i].label, verdicts[i]))
        .collect();
    s.push_str(&format!(
        "\nVerdicts naming a wrong effect: {}{}\n",
        wrong.len(),
        if wrong.is_empty() {
            String::new()
        } else {
            format!(": {}", wrong.join(", "))
        }
    ));
    let shrinks: Vec<f64> = (0..cases.len())
        .filter(|&i| cases[i].is_right(&verdicts[i]))
        .filter_map(|i| res[i].as_ref().ok().map(|o| o.check_shrink))
        .collect();
    s.push_str(&format!(
        "Median check shrink of the right verdicts: {:.3} (n = {})\n",
        median(shrinks.clone()),
        shrinks.len()
    ));
    let secs: f64 = res
        .iter()
        .filter_map(|r| r.as_ref().ok().map(|o| o.seconds))
        .sum();
    s.push_str(&format!(
        "Diagnosis time, summed over the cases: {secs:.0} s\n\n"
    ));
    s
}

/// A row per case.
fn per_case(cases: &[Case], truths: &[Truth], res: &[Result<Outcome, String>]) -> String {
    let mut s = String::new();
    s.push_str("| case | label | truth | verdict | ok | isolation.equation | isolation.names | check shrink | s |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|\n");
    for (i, c) in cases.iter().enumerate() {
        match &res[i] {
            Ok(o) => s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {:.3} | {:.1} |\n",
                c.id,
                c.label,
                truths[i].label,
                o.verdict,
                if c.is_right(&o.verdict) { "yes" } else { "no" },
                o.equation,
                o.names,
                o.check_shrink,
                o.seconds
            )),
            Err(e) => s.push_str(&format!(
                "| {} | {} | {} | error | no | - | - | - | - |\n\n    {e}\n\n",
                c.id, c.label, truths[i].label
            )),
        }
    }
    s
}

fn git_commit() -> String {
    Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "?".into())
}

/// Run `f(i)` for i in 0..n on two threads, results in order.
fn on_two_threads<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let next = AtomicUsize::new(0);
    let out: Mutex<Vec<Option<T>>> = Mutex::new((0..n).map(|_| None).collect());
    std::thread::scope(|sc| {
        for _ in 0..2 {
            sc.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                if i >= n {
                    break;
                }
                let r = f(i);
                out.lock().expect("results")[i] = Some(r);
            });
        }
    });
    out.into_inner()
        .expect("results")
        .into_iter()
        .map(|r| r.expect("every job ran"))
        .collect()
}

fn write_logs(dir: &Path, fit: &Log, check: &Log) {
    std::fs::create_dir_all(dir).expect("case directory");
    for (suffix, every, _) in RESOLUTIONS {
        std::fs::write(dir.join(format!("fit{suffix}.csv")), fit.to_csv(every)).expect("fit log");
        std::fs::write(dir.join(format!("check{suffix}.csv")), check.to_csv(every))
            .expect("check log");
    }
}

/// Write every case's logs, run the release `host-sim gap` on them at both
/// resolutions, print the tables and write them to `target/gap-<family>.md`.
/// Panics when a diagnosis errors or its JSON has no verdict.
pub fn confusion_run(family: Family, cases: &[Case]) {
    let t_start = Instant::now();
    let target = target_dir();
    let bin = host_sim_release(&target);
    let root = target.join(format!("gap-{}", family.name));

    // Logs and, per case, the visibility of the rig's effects on the fit run
    // (for a pair also of each member alone: which one is larger).
    let vis: Vec<Vec<f64>> = on_two_threads(cases.len(), |i| {
        let c = &cases[i];
        let rig = c.rig();
        write_logs(
            &root.join(&c.id),
            &run(&rig, &c.fit, true),
            &run(&rig, &c.check, true),
        );
        let mut v = vec![cases::visibility(&c.effects, &c.fit)];
        if c.kind == Kind::Pair {
            for e in &c.effects {
                v.push(cases::visibility(std::slice::from_ref(e), &c.fit));
            }
        }
        v
    });
    let truths: Vec<Truth> = cases
        .iter()
        .zip(&vis)
        .map(|(c, v)| truth_of(c, v))
        .collect();
    let t_logs = t_start.elapsed().as_secs_f64();

    // Diagnoses: every case at both resolutions.
    let jobs: Vec<(usize, usize)> = (0..RESOLUTIONS.len())
        .flat_map(|r| (0..cases.len()).map(move |i| (r, i)))
        .collect();
    let results = on_two_threads(jobs.len(), |j| {
        let (r, i) = jobs[j];
        let out = diagnose(&bin, &root.join(&cases[i].id), RESOLUTIONS[r].0);
        match &out {
            Ok(o) => eprintln!(
                "{} {:>5}: {:<20} -> {:<20} ({:.1} s)",
                cases[i].id, RESOLUTIONS[r].2, truths[i].label, o.verdict, o.seconds
            ),
            Err(e) => eprintln!("{} {:>5}: {e}", cases[i].id, RESOLUTIONS[r].2),
        }
        out
    });

    let mut md = format!("# Gap diagnosis on the {} family of rigs\n\n", family.name);
    md.push_str(&format!(
        "Commit {} ({}). {} cases, logs of 10 s \
         at 1 ms (and every 10th row: 10 ms), realistic sensors, controllers of dca_core at \
         the 1 ms board tick. Logs {:.0} s, whole run {:.0} s (2 threads).\n\n",
        git_commit(),
        family.sources,
        cases.len(),
        t_logs,
        t_start.elapsed().as_secs_f64()
    ));
    md.push_str(
        "Visibility: RMS of the difference to the nominal rig (exact sensors, same \
                 controller) over xi, xo (in 13 um) and p1, p2 (in 5.2 kPa) on the fit run.\n\n",
    );
    md.push_str(
        "| case | label | kind | truth | form(s) | magnitude | fit | check | visibility |\n",
    );
    md.push_str("|---|---|---|---|---|---|---|---|---|\n");
    for (c, t) in cases.iter().zip(&truths) {
        let forms: Vec<&str> = c.effects.iter().map(|e| e.form()).collect();
        md.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} {} | {} {} | {:.1} |\n",
            c.id,
            c.label,
            c.kind.name(),
            t.label,
            if forms.is_empty() {
                "-".into()
            } else {
                forms.join(" + ")
            },
            c.magnitude,
            c.fit.scenario.name(),
            c.fit.ctl.label(),
            c.check.scenario.name(),
            c.check.ctl.label(),
            t.visibility
        ));
    }
    md.push('\n');
    let n = cases.len();
    for (r, (_, _, title)) in RESOLUTIONS.iter().enumerate() {
        md.push_str(&tables(
            &format!("Logs at {title}"),
            cases,
            &truths,
            &results[r * n..(r + 1) * n],
        ));
    }
    md.push_str(&format!(
        "Total wall time: {:.0} s\n",
        t_start.elapsed().as_secs_f64()
    ));
    println!("{md}");
    let md_path = target.join(format!("gap-{}.md", family.name));
    std::fs::write(&md_path, &md).unwrap_or_else(|e| panic!("write {}: {e}", md_path.display()));
    let errors: Vec<&String> = results.iter().filter_map(|r| r.as_ref().err()).collect();
    assert!(
        errors.is_empty(),
        "{} diagnoses failed: {errors:?}",
        errors.len()
    );
}

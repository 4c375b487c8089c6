//! The fuzz harnesses (`dca_tests::fuzz`) on stable Rust: every seed of
//! `tests/fuzz/corpus/<target>/`, every reproducer of
//! `tests/fuzz/regressions/<target>/`, and a few thousand pseudo-random
//! inputs per target from a fixed-seed generator (mutated seeds and
//! target-specific generators), so that `cargo test` exercises each harness
//! and its invariants without libFuzzer.
//!
//! A reproducer whose name starts with `known-defect-` documents a defect
//! whose fix lies outside this crate's files: it is run and reported (still
//! present, or fixed), never failed on. `DCA_FUZZ_CASES=n` sets the number of
//! pseudo-random inputs per target; `DCA_FUZZ_WRITE_SEEDS=1` rewrites the
//! generated seeds (`gen-*`) instead of checking them.

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use dca_app::settings::PARAMS;
use dca_tests::fuzz::{self, seeds, take_known_defects, Harness, TARGETS};
use host_sim::io::runlog::RunLog;
use host_sim::sim::batch::SweepParam;
use host_sim::sim::config::{ConfigFile, ScenarioFile};

/// Pseudo-random inputs per target when `DCA_FUZZ_CASES` is not set.
const DEFAULT_CASES: usize = 10_000;

/// Prefix of reproducers of defects that are not fixed yet.
const KNOWN_PREFIX: &str = "known-defect-";

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

/// The files of `dir`, sorted (none if it does not exist).
fn files(dir: &Path) -> Vec<PathBuf> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    v.sort();
    v
}

/// Run one input; the panic message if the harness panicked.
fn run(h: Harness, data: &[u8]) -> Result<(), String> {
    catch_unwind(AssertUnwindSafe(|| h(data))).map_err(|e| {
        e.downcast_ref::<String>()
            .cloned()
            .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "(no message)".into())
    })
}

fn cases() -> usize {
    std::env::var("DCA_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(DEFAULT_CASES)
}

#[test]
fn every_seed_passes_every_target_has_seeds() {
    let mut failures = Vec::new();
    for (name, h) in TARGETS {
        let seeds = files(&fuzz_dir().join("corpus").join(name));
        assert!(!seeds.is_empty(), "no seeds for target {name}");
        let mut run_count = 0;
        for f in &seeds {
            let data = std::fs::read(f).unwrap();
            if let Err(m) = run(h, &data) {
                failures.push(format!("{}: {m}", f.display()));
            }
            for d in take_known_defects() {
                failures.push(format!("{}: hits known defect {d}", f.display()));
            }
            run_count += 1;
        }
        assert!(run_count > 0);
        eprintln!("{name}: {run_count} seeds");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The text seeds exercise the accepting paths: every seed whose name does
/// not say it is bad is accepted by its loader (so the harness's checks of
/// accepted input run on it).
#[test]
fn text_seeds_are_accepted_unless_named_bad() {
    let bad = |n: &str| {
        ["bad-", "errors-", "unknown-"]
            .iter()
            .any(|p| n.starts_with(p))
    };
    let mut checked = 0;
    for target in ["runlog", "scenario_toml", "config_toml"] {
        for f in files(&fuzz_dir().join("corpus").join(target)) {
            let name = f.file_name().unwrap().to_string_lossy().to_string();
            let text = std::fs::read_to_string(&f).unwrap();
            let ok = match target {
                "runlog" => RunLog::parse(&text, &name)
                    .map(|_| ())
                    .map_err(|e| e.to_string()),
                "scenario_toml" => ScenarioFile::load_str(&text, &name, "seed")
                    .map(|_| ())
                    .map_err(|e| e.to_string()),
                _ if name.ends_with(".txt") => text
                    .lines()
                    .try_for_each(|l| SweepParam::parse(l).map(|_| ()))
                    .map_err(|e| e.to_string()),
                _ => ConfigFile::parse_str(&text, &name)
                    .and_then(|c| c.preset(&name).map(|_| ()))
                    .map_err(|e| e.to_string()),
            };
            assert_eq!(ok.is_ok(), !bad(&name), "{target}/{name}: {ok:?}");
            checked += 1;
        }
    }
    assert!(checked >= 10, "{checked} text seeds");
}

#[test]
fn generated_seeds_are_current() {
    let write = std::env::var("DCA_FUZZ_WRITE_SEEDS").is_ok_and(|v| v == "1");
    let mut stale = Vec::new();
    let generated = seeds::binary_seeds();
    for (target, name, data) in &generated {
        assert!(name.starts_with(seeds::PREFIX), "{name}");
        let dir = fuzz_dir().join("corpus").join(target);
        let path = dir.join(name);
        if write {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(&path, data).unwrap();
        } else if std::fs::read(&path).ok().as_deref() != Some(&data[..]) {
            stale.push(path.display().to_string());
        }
    }
    // No generated seed on disk that the generator no longer makes.
    for (target, _) in TARGETS {
        for f in files(&fuzz_dir().join("corpus").join(target)) {
            let n = f.file_name().unwrap().to_string_lossy().to_string();
            if n.starts_with(seeds::PREFIX)
                && !generated.iter().any(|(t, g, _)| t == &target && *g == n)
            {
                if write {
                    std::fs::remove_file(&f).unwrap();
                } else {
                    stale.push(format!("{} (no longer generated)", f.display()));
                }
            }
        }
    }
    assert!(
        stale.is_empty(),
        "generated seeds are stale; rewrite them with\n  DCA_FUZZ_WRITE_SEEDS=1 cargo test -p dca-tests --test fuzz_corpus generated_seeds_are_current\n{}",
        stale.join("\n")
    );
}

#[test]
fn regressions_stay_fixed() {
    let mut failures = Vec::new();
    for (name, h) in TARGETS {
        for f in files(&fuzz_dir().join("regressions").join(name)) {
            let data = std::fs::read(&f).unwrap();
            let file = f.file_name().unwrap().to_string_lossy().to_string();
            let r = run(h, &data);
            let known = take_known_defects();
            if file.starts_with(KNOWN_PREFIX) {
                match (&r, known.is_empty()) {
                    (Err(m), _) => failures.push(format!("{file}: {m}")),
                    (Ok(()), false) => eprintln!("{name}/{file}: known defect still present: {known:?}"),
                    (Ok(()), true) => eprintln!(
                        "{name}/{file}: no longer reproduces: drop the '{KNOWN_PREFIX}' prefix to keep it as a regression test"
                    ),
                }
            } else {
                if let Err(m) = r {
                    failures.push(format!("{name}/{file}: {m}"));
                }
                if !known.is_empty() {
                    failures.push(format!("{name}/{file}: hits known defects {known:?}"));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// xorshift64*: small, fixed-seed, the same stream everywhere.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn byte(&mut self) -> u8 {
        self.next() as u8
    }
    fn chance(&mut self, one_in: usize) -> bool {
        self.below(one_in) == 0
    }
    fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
        &v[self.below(v.len())]
    }
}

/// Tokens worth inserting into text inputs.
const TOKENS: &[&str] = &[
    "0",
    "-0.0",
    "1e308",
    "-1e308",
    "1e-320",
    "nan",
    "inf",
    "-inf",
    "NaN",
    "1e999",
    "4294967296",
    "18446744073709551616",
    ",",
    "\n",
    "\r\n",
    "#",
    "=",
    "[",
    "]",
    "\"",
    "{",
    "}",
    ".",
    " ",
    "t_s",
    "ref_m",
    "type = \"piecewise\"",
    "type = \"ramp\"",
    "[plant.effects.air]\nfraction = 0.01\n",
    "kappa = ",
    "frequency_hz = ",
    "amplitude = ",
    "slope_per_s = ",
    "t0_s = ",
    "np = ",
    "nc = ",
    "ts_s = ",
    "rw = ",
    "\u{feff}",
    "\u{e9}",
];

/// Apply 1 to 8 random edits to `data` (bytes, tokens, splices from `pool`).
fn mutate(rng: &mut Rng, data: &mut Vec<u8>, pool: &[Vec<u8>]) {
    for _ in 0..1 + rng.below(8) {
        let n = data.len();
        match rng.below(8) {
            0 if n > 0 => {
                let i = rng.below(n);
                data[i] ^= 1 << rng.below(8);
            }
            1 if n > 0 => {
                let i = rng.below(n);
                data[i] = rng.byte();
            }
            2 => data.insert(rng.below(n + 1), rng.byte()),
            3 if n > 0 => {
                let i = rng.below(n);
                let len = 1 + rng.below(8.min(n - i));
                data.drain(i..i + len);
            }
            4 => {
                let t = rng.pick(TOKENS).as_bytes();
                let at = rng.below(n + 1);
                data.splice(at..at, t.iter().copied());
            }
            5 if n > 0 => {
                let i = rng.below(n);
                let len = 1 + rng.below(16.min(n - i));
                let chunk = data[i..i + len].to_vec();
                let at = rng.below(n + 1);
                data.splice(at..at, chunk);
            }
            6 if !pool.is_empty() => {
                let other = rng.pick(pool);
                let (a, b) = (rng.below(other.len() + 1), rng.below(other.len() + 1));
                let (a, b) = (a.min(b), a.max(b));
                let at = rng.below(n + 1);
                data.splice(at..at, other[a..b].iter().copied());
            }
            _ => {
                let at = rng.below(n + 1);
                data.truncate(at.max(n.saturating_sub(32)));
            }
        }
    }
}

/// A number near an edge of `[lo, hi]`, as text the console accepts or
/// nearly accepts.
fn edge_text(rng: &mut Rng, bound: f64, lo: f64, hi: f64) -> String {
    match rng.below(8) {
        0 => format!("{bound:e}"),
        1 => format!("{}", lo),
        2 => format!("{}", hi),
        3 => format!("{:.6e}", (hi as f32) as f64),
        4 => format!("{:.6e}", (lo as f32) as f64),
        5 => format!("{:.8e}", lo + (hi - lo) * rng.below(1001) as f64 / 1000.0),
        6 => format!("{}", rng.below(64)),
        _ => format!("-{}", rng.below(3)),
    }
}

/// A console session from a small grammar.
fn console_case(rng: &mut Rng) -> Vec<u8> {
    let mut v = vec![rng.byte() & 0x3f, rng.byte(), rng.byte(), rng.byte()];
    if rng.chance(2) {
        // Mostly an intact flash: the store/load round trip is checked.
        v[0] &= !0x03;
    }
    for _ in 0..1 + rng.below(10) {
        let line = match rng.below(14) {
            0..=4 => {
                let p = rng.pick(&PARAMS);
                let (b, lo, hi) = if rng.chance(2) {
                    (p.min, p.min, p.max)
                } else {
                    (p.max, p.min, p.max)
                };
                format!("set {} {}", p.name, edge_text(rng, b, lo, hi))
            }
            5 => "store".into(),
            6 => "load".into(),
            7 => format!("get {}", rng.pick(&PARAMS).name),
            8 => rng
                .pick(&[
                    "arm", "disarm", "stop", "clear", "defaults", "status", "fault", "get",
                ])
                .to_string(),
            9 => format!("goto {}", rng.below(120) as i64 - 10),
            10 => format!("sine {} {}", rng.below(70), rng.below(12)),
            11 => format!(
                "controller {}",
                rng.pick(&["mpc-eso", "mpc", "pid", "fuzzy-pid", "x"])
            ),
            12 => format!("preset {}", rng.pick(&["paper", "fast", "slow"])),
            _ => format!("telemetry on {}", rng.below(20_000)),
        };
        v.extend_from_slice(line.as_bytes());
        v.extend_from_slice(if rng.chance(4) { b"\n" } else { b"\r\n" });
    }
    v
}

/// A run log of a few rows, sometimes with odd times or values.
fn runlog_case(rng: &mut Rng) -> Vec<u8> {
    let mut s = String::from("# dca-log v1\n# controller=pid\n");
    let mut cols = vec![
        "t_s", "ref_m", "vcmd_mps", "xi_m", "xo_m", "p1_pa", "p2_pa", "ft_n",
    ];
    if rng.chance(3) {
        cols.push("z1_m");
    }
    if rng.chance(4) {
        let i = rng.below(cols.len());
        let j = rng.below(cols.len());
        cols.swap(i, j);
    }
    s += &cols.join(",");
    s.push('\n');
    let t0 = *rng.pick(&[0.0, 1.0e-9, 1.0e6, -1.0e308, -1.7e308, 1.0e300]);
    let dt = *rng.pick(&[1.0e-3, 1.0e-4, 1.0e-300, 1.0e308, 0.5, 1.7e308]);
    for k in 0..2 + rng.below(5) {
        let t = if rng.chance(8) {
            t0 + dt * (k as f64 + 0.5)
        } else {
            t0 + dt * k as f64
        };
        let row: Vec<String> = cols
            .iter()
            .map(|c| {
                if *c == "t_s" {
                    format!("{t:e}")
                } else {
                    match rng.below(12) {
                        0 => "1e308".into(),
                        1 => "nan".into(),
                        2 => String::new(),
                        _ => format!("{}", rng.below(1000) as f64 / 7.0),
                    }
                }
            })
            .collect();
        s += &row.join(",");
        s.push('\n');
    }
    s.into_bytes()
}

/// A frame case: a structured corruption, or a stream of random frames.
fn frame_case(rng: &mut Rng) -> Vec<u8> {
    let mut v = vec![rng.byte() | 1];
    // seq: small (so that frames can be expected) or anything.
    let seq = if rng.chance(2) {
        rng.below(3) as u32
    } else {
        rng.next() as u32
    };
    v.extend_from_slice(&seq.to_le_bytes());
    for _ in 0..24 {
        v.push(rng.byte());
    }
    v.push(rng.byte());
    for _ in 0..rng.below(4) {
        v.extend_from_slice(&[rng.byte(), rng.byte(), rng.byte()]);
    }
    v
}

/// A settings case: a valid image changed by a few edits.
fn settings_case(rng: &mut Rng) -> Vec<u8> {
    let mut v = vec![1, rng.byte(), if rng.chance(5) { 0 } else { 1 }];
    for _ in 0..1 + rng.below(4) {
        let op = rng.byte();
        v.push(op);
        if op % 6 == 2 || op % 6 == 3 {
            v.extend_from_slice(&(rng.below(PARAMS.len()) as u16).to_le_bytes());
        } else {
            v.extend_from_slice(&(rng.below(0x1d0) as u16).to_le_bytes());
        }
        for _ in 0..8 {
            v.push(rng.byte());
        }
    }
    v
}

#[test]
fn pseudo_random_inputs_pass() {
    let n = cases();
    let mut failures = Vec::new();
    let mut known: BTreeMap<&str, usize> = BTreeMap::new();
    for (t, (name, h)) in TARGETS.iter().enumerate() {
        let pool: Vec<Vec<u8>> = files(&fuzz_dir().join("corpus").join(name))
            .iter()
            .map(|f| std::fs::read(f).unwrap())
            .collect();
        assert!(!pool.is_empty(), "no seeds for {name}");
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15 ^ (t as u64 + 1).wrapping_mul(0x1234_5678_9abc));
        let started = std::time::Instant::now();
        let (mut ran, mut failed) = (0, 0);
        for i in 0..n {
            let data = if i % 2 == 0 {
                let mut d = rng.pick(&pool).clone();
                mutate(&mut rng, &mut d, &pool);
                d
            } else {
                match *name {
                    "console" => console_case(&mut rng),
                    "frame" => frame_case(&mut rng),
                    "settings_image" => settings_case(&mut rng),
                    "runlog" => runlog_case(&mut rng),
                    _ => {
                        let mut d = rng.pick(&pool).clone();
                        mutate(&mut rng, &mut d, &pool);
                        mutate(&mut rng, &mut d, &pool);
                        d
                    }
                }
            };
            if let Err(m) = run(*h, &data) {
                failed += 1;
                if failed <= 3 {
                    let shown = String::from_utf8_lossy(fuzz_bytes(&data));
                    failures.push(format!("{name} case {i} {shown:?}: {m}"));
                }
            }
            for d in take_known_defects() {
                *known.entry(d).or_default() += 1;
            }
            ran += 1;
        }
        assert_eq!(ran, n);
        eprintln!(
            "{name}: {ran} pseudo-random inputs in {:.2} s, {failed} failed",
            started.elapsed().as_secs_f64()
        );
    }
    for (d, k) in &known {
        eprintln!("known defect {d}: hit by {k} inputs");
    }
    assert!(n > 0);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// At most the first 200 bytes, for messages.
fn fuzz_bytes(d: &[u8]) -> &[u8] {
    &d[..d.len().min(200)]
}

#[test]
fn every_harness_is_reachable_by_name() {
    for (name, _) in TARGETS {
        assert!(fuzz::harness(name).is_some());
    }
    assert!(fuzz::harness("nope").is_none());
}

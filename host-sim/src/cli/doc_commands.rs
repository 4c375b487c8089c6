//! Every command the manuals show (README.md, docs/*.md) runs as written.
//!
//! The manuals' rule: a ```` ```sh ```` block holds commands that run as
//! written from the repository root; a ```` ```text ```` block holds output
//! or a synopsis (`host-sim run --scenario NAME|FILE.toml ...`); a block
//! without a language must not look like commands. A command that needs a
//! board (`--port DEVICE`) sits under a comment or a sentence that says so.
//!
//! `documented_commands_parse` (part of `cargo test`) checks every command:
//! `host-sim` ones through this binary's own parser, `cargo test` ones against
//! the workspace's packages, test targets and test names, the cargo aliases
//! against `.cargo/config.toml`, scripts and fuzz targets against the files.
//! `documented_commands_run` (`--ignored`; CI's stage "documented commands"
//! and, where QEMU runs, the firmware stage) runs them end to end:
//!
//! * `DCA_DOCS_RUN=host`: every command that needs neither a board nor QEMU,
//!   in a scratch directory laid out like the repository root
//!   (target/doc-commands: the repository's folders linked in, its own `out/`);
//! * `DCA_DOCS_RUN=qemu`: the commands that start QEMU, and those for a board
//!   against the emulated one (`--port ...` replaced by `--qemu`, as
//!   docs/firmware.md tells a reader to), with what reads their captures.
//!
//! Files a command reads that the manuals assume the reader has (`my-test.toml`,
//! the rig's recorded runs) are made first: from the manuals' own TOML blocks
//! whose first line names the file, or by a documented kind of command.
//! Commands that other stages run (`cargo test`, the firmware and fuzzing
//! scripts), that install tools or flash a board, and templates with
//! placeholders are checked but not run here; the run says which and why.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use clap::Parser as _;

use super::Cli;

/// The repository root.
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .expect("repository root")
}

/// README.md and every docs/*.md, as paths relative to the root.
fn manuals() -> Vec<String> {
    let mut docs: Vec<String> = std::fs::read_dir(root().join("docs"))
        .expect("docs/")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    docs.sort();
    std::iter::once("README.md".to_string())
        .chain(docs)
        .collect()
}

/// A fenced code block.
#[derive(Clone, Debug)]
struct Block {
    /// `docs/x.md:12` (the opening fence).
    at: String,
    /// The info string: `sh`, `text`, `toml`, or empty.
    lang: String,
    /// The prose line just above the block.
    intro: String,
    /// The lines inside, with their line numbers.
    lines: Vec<(usize, String)>,
}

fn blocks(file: &str, text: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut open: Option<Block> = None;
    let mut last_prose = String::new();
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        match (&mut open, t.strip_prefix("```")) {
            (None, Some(lang)) => {
                open = Some(Block {
                    at: format!("{file}:{}", i + 1),
                    lang: lang.trim().to_string(),
                    intro: last_prose.clone(),
                    lines: Vec::new(),
                })
            }
            (Some(_), Some("")) => out.extend(open.take()),
            (Some(b), _) => b.lines.push((i + 1, line.to_string())),
            (None, None) if !t.is_empty() => last_prose = t.to_string(),
            (None, None) => {}
        }
    }
    out
}

/// One command of a ```` ```sh ```` block.
#[derive(Clone, Debug)]
struct DocCommand {
    /// `docs/x.md:71`.
    at: String,
    /// As written: continuation lines joined, a trailing `# comment` dropped.
    text: String,
    /// The comment above it in its block and the sentence above the block.
    context: String,
    /// The directory it runs in, relative to the root (after a `cd` above it).
    dir: String,
}

impl DocCommand {
    /// The words after leading `NAME=value` assignments.
    fn words(&self) -> Vec<&str> {
        self.text
            .split_whitespace()
            .skip_while(|w| is_assignment(w))
            .collect()
    }

    /// The arguments after `cargo run --release -p host-sim --`, if it is one.
    fn host_sim_args(&self) -> Option<Vec<String>> {
        let (head, tail) = self.text.split_once(" -- ")?;
        let head: Vec<&str> = head.split_whitespace().collect();
        (head == ["cargo", "run", "--release", "-p", "host-sim"])
            .then(|| tail.split_whitespace().map(str::to_string).collect())
    }
}

fn is_assignment(w: &str) -> bool {
    w.split_once('=').is_some_and(|(k, _)| {
        !k.is_empty()
            && k.chars()
                .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
    })
}

/// The commands of a file's ```` ```sh ```` blocks; an error for a block
/// without a language whose first line is a command.
fn commands(file: &str, text: &str) -> Result<Vec<DocCommand>, String> {
    let mut out = Vec::new();
    for b in blocks(file, text) {
        let first = b.lines.iter().map(|l| l.1.trim()).find(|l| !l.is_empty());
        if b.lang.is_empty() && first.is_some_and(looks_like_a_command) {
            return Err(format!(
                "{}: a block of commands without a language: ```sh if they run as written, \
                 ```text for a synopsis or output",
                b.at
            ));
        }
        if b.lang != "sh" {
            continue;
        }
        let mut comment = String::new();
        let mut dir = String::new();
        let mut line = String::new();
        let mut start = 0;
        for (n, l) in &b.lines {
            let t = l.trim();
            if line.is_empty() {
                if t.is_empty() {
                    continue;
                }
                if let Some(c) = t.strip_prefix('#') {
                    comment = c.trim().to_string();
                    continue;
                }
                start = *n;
            }
            let (body, more) = match t.strip_suffix('\\') {
                Some(b) => (b, true),
                None => (t, false),
            };
            line.push_str(body.trim());
            line.push(' ');
            if more {
                continue;
            }
            // A trailing comment: ` # ...` after the command.
            let text = match line.split_once(" # ") {
                Some((cmd, _)) => cmd.trim().to_string(),
                None => line.trim().to_string(),
            };
            line.clear();
            let c = DocCommand {
                at: format!("{file}:{start}"),
                text,
                context: format!("{comment} / {}", b.intro),
                dir: dir.clone(),
            };
            if let ["cd", d] = c.words()[..] {
                dir = Path::new(&dir).join(d).to_string_lossy().into_owned();
            }
            out.push(c);
        }
    }
    Ok(out)
}

fn looks_like_a_command(line: &str) -> bool {
    ["cargo ", "host-sim ", "rustup ", "python3 ", "bash ", "./"]
        .iter()
        .any(|p| line.starts_with(p))
}

/// What CI does with a documented command.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Plan {
    /// Run in the host stage.
    Run,
    /// Starts QEMU: run in the QEMU stage.
    Qemu,
    /// Needs a board: in the QEMU stage, this host-sim command (the
    /// documented one with `--port ...` replaced by `--qemu`) runs instead.
    Board(Vec<String>),
    /// Not run by this test; why.
    Skip(String),
}

/// Check a command as far as it can be checked without running it, and say
/// what CI does with it.
fn check(c: &DocCommand) -> Result<Plan, String> {
    let w = c.words();
    let skip = |why: &str| Ok(Plan::Skip(why.to_string()));
    if let Some(args) = c.host_sim_args() {
        return check_host_sim(c, args);
    }
    match w[..] {
        ["cargo", "test"] => skip("the tests stage runs it"),
        ["cargo", "test", ..] => check_cargo_test(c),
        ["cargo", "install", ..] => skip("installs a tool"),
        ["cargo", "run", ..] => Err("`cargo run` of a package other than host-sim".into()),
        ["cargo", toolchain, "fuzz", ..] if toolchain.starts_with('+') => check_fuzz(c),
        ["cargo", alias] => {
            let config = read(".cargo/config.toml")?;
            let table: toml::Table = config.parse().map_err(|e| format!("{e}"))?;
            let known = table
                .get("alias")
                .and_then(|a| a.as_table())
                .is_some_and(|a| a.contains_key(alias));
            if !known {
                return Err(format!(
                    "`cargo {alias}`: no such alias in .cargo/config.toml"
                ));
            }
            if alias.ends_with("-run") {
                skip("flashes a board through a debug probe")
            } else {
                skip("the firmware stage (.ci/firmware.sh) runs it")
            }
        }
        ["rustup", ..] => skip("toolchain set-up (CI's set-up does it)"),
        ["python3" | "bash", script, ..] => {
            let path = Path::new(&c.dir).join(script);
            if !root().join(&path).is_file() {
                return Err(format!("{}: no such file", path.display()));
            }
            let by = ci_scripts_mentioning(&path.to_string_lossy());
            match by.first() {
                Some(s) => skip(&format!("CI runs it ({s})")),
                None => Err(format!("{script}: no CI stage runs it")),
            }
        }
        ["cd", d] => {
            let path = Path::new(&c.dir).join(d);
            if root().join(&path).is_dir() {
                skip("changes directory")
            } else {
                Err(format!("{}: no such directory", path.display()))
            }
        }
        ["mkdir", ..] => skip("makes a scratch directory"),
        ["cp", ..] if has_placeholder(&c.text) => skip("a template (placeholders)"),
        _ => Err("a command of a form this test does not know: add a rule".into()),
    }
}

fn read(rel: &str) -> Result<String, String> {
    std::fs::read_to_string(root().join(rel)).map_err(|e| format!("{rel}: {e}"))
}

/// The CI scripts (.ci/*) whose text contains `what`.
fn ci_scripts_mentioning(what: &str) -> Vec<String> {
    let mut out: Vec<String> = std::fs::read_dir(root().join(".ci"))
        .map(|d| {
            d.filter_map(|e| e.ok())
                .filter(|e| {
                    std::fs::read_to_string(e.path()).is_ok_and(|t| t.contains(what))
                        || what.ends_with(&*e.file_name().to_string_lossy())
                })
                .map(|e| format!(".ci/{}", e.file_name().to_string_lossy()))
                .collect()
        })
        .unwrap_or_default();
    out.sort();
    out
}

fn has_placeholder(text: &str) -> bool {
    text.contains("...") || text.contains('<')
}

/// Options whose values are files a host-sim command reads.
const INPUTS: [&str; 6] = [
    "--fit",
    "--check",
    "--script",
    "--scenario",
    "--config",
    "--plant",
];
/// Options whose values are files or directories a host-sim command writes.
const OUTPUTS: [&str; 8] = [
    "--rig-out",
    "--log",
    "--capture",
    "--out",
    "--logs",
    "--report",
    "--json",
    "--csv",
];

/// The values of `options` in `args` that are paths (not preset names).
fn values_of<'a>(args: &'a [String], options: &[&str]) -> Vec<&'a str> {
    args.windows(2)
        .filter(|w| options.contains(&w[0].as_str()))
        .map(|w| w[1].as_str())
        .filter(|v| v.contains('/') || v.contains('.'))
        .collect()
}

/// Why `console --scope` is checked but not run here: it draws on a terminal
/// and ends on a key, so it cannot run with no terminal and stdin closed.
const SCOPE_SKIP: &str = "the live view needs a terminal: hil_pil's tmux test runs it against \
                          the emulated board (.ci/firmware.sh)";

fn check_host_sim(c: &DocCommand, args: Vec<String>) -> Result<Plan, String> {
    let argv = std::iter::once("host-sim".to_string()).chain(args.iter().cloned());
    Cli::try_parse_from(argv).map_err(|e| format!("does not parse: {e}"))?;
    let has = |o: &str| args.iter().any(|a| a == o);
    if has("--port") {
        if !c.context.to_lowercase().contains("board") {
            return Err(format!(
                "needs a board (--port) but neither its comment nor the sentence above \
                 its block says so: {}",
                c.context
            ));
        }
        // docs/firmware.md: "Replace `--port ...` by `--qemu` for the emulated board".
        let mut emulated = Vec::new();
        let mut it = args.iter();
        while let Some(a) = it.next() {
            match a.as_str() {
                "--port" => {
                    it.next();
                    emulated.push("--qemu".to_string());
                }
                "--console" | "--baud" => {
                    it.next();
                }
                _ => emulated.push(a.clone()),
            }
        }
        let argv = std::iter::once("host-sim".to_string()).chain(emulated.iter().cloned());
        Cli::try_parse_from(argv)
            .map_err(|e| format!("with --qemu for --port it does not parse: {e}"))?;
        if has("--scope") {
            return Ok(Plan::Skip(SCOPE_SKIP.into()));
        }
        return Ok(Plan::Board(emulated));
    }
    Ok(if has("--scope") {
        Plan::Skip(SCOPE_SKIP.into())
    } else if has("--qemu") {
        Plan::Qemu
    } else {
        Plan::Run
    })
}

/// A workspace member's directory by package name.
fn member_dir(name: &str) -> Option<PathBuf> {
    let ws: toml::Table = read("Cargo.toml").ok()?.parse().ok()?;
    ws.get("workspace")?
        .get("members")?
        .as_array()?
        .iter()
        .filter_map(|m| m.as_str())
        .map(|m| root().join(m))
        .find(|d| {
            std::fs::read_to_string(d.join("Cargo.toml"))
                .ok()
                .and_then(|t| t.parse::<toml::Table>().ok())
                .and_then(|t| t.get("package")?.get("name")?.as_str().map(str::to_string))
                .is_some_and(|n| n == name)
        })
}

fn check_cargo_test(c: &DocCommand) -> Result<Plan, String> {
    let w = c.words();
    let (cargo_args, test_args) = match w.iter().position(|a| *a == "--") {
        Some(i) => (&w[2..i], &w[i + 1..]),
        None => (&w[2..], &[][..]),
    };
    let mut package = None;
    let mut target = None;
    let mut filter = None;
    let mut it = cargo_args.iter();
    while let Some(a) = it.next() {
        match *a {
            "-p" | "--package" => package = it.next().copied(),
            "--test" => target = it.next().copied(),
            "--release" => {}
            f if !f.starts_with('-') && filter.is_none() => filter = Some(f),
            other => {
                return Err(format!(
                    "cargo test option `{other}` not known to this test"
                ))
            }
        }
    }
    let dir = match package {
        Some(p) => member_dir(p).ok_or(format!("no workspace member `{p}`"))?,
        None => root(),
    };
    let source = match target {
        Some(t) => {
            let f = dir.join("tests").join(format!("{t}.rs"));
            std::fs::read_to_string(&f)
                .map_err(|_| format!("no test target `{t}` ({})", f.display()))?
        }
        None => String::new(),
    };
    if let Some(f) = filter {
        if !source.contains(&format!("fn {f}")) && !source.contains(&format!("_{f}")) {
            return Err(format!("no test whose name contains `{f}`"));
        }
    }
    for a in test_args {
        if ![
            "--nocapture",
            "--ignored",
            "--include-ignored",
            "--exact",
            "--test-threads",
        ]
        .contains(a)
            && a.parse::<u32>().is_err()
        {
            return Err(format!("libtest option `{a}` not known to this test"));
        }
    }
    if test_args.contains(&"--ignored") {
        return Ok(Plan::Skip(
            "an ignored test: a measurement of minutes, or a suite CI's validation stage runs"
                .into(),
        ));
    }
    Ok(Plan::Run)
}

fn check_fuzz(c: &DocCommand) -> Result<Plan, String> {
    let w = c.words();
    let fuzz = root().join(&c.dir).join("fuzz");
    if !fuzz.join("Cargo.toml").is_file() {
        return Err(format!(
            "no cargo-fuzz project in {}",
            Path::new(&c.dir).join("fuzz").display()
        ));
    }
    let rest: Vec<&str> = w[3..].iter().copied().take_while(|a| *a != "--").collect();
    match rest.first() {
        Some(&"list") => {}
        Some(&("run" | "tmin" | "build" | "cmin")) => {
            let target = rest[1..]
                .iter()
                .find(|a| !a.starts_with('-'))
                .ok_or("no fuzz target named")?;
            if !fuzz
                .join("fuzz_targets")
                .join(format!("{target}.rs"))
                .is_file()
            {
                return Err(format!("no fuzz target `{target}`"));
            }
            // The directories and the dictionary it reads, unless a template
            // or the scratch corpus the block makes with mkdir.
            for a in w.iter().skip(4) {
                let path = a.strip_prefix("-dict=").unwrap_or(a);
                if path.contains('/') && !has_placeholder(path) && !path.starts_with("fuzz/work") {
                    let p = root().join(&c.dir).join(path);
                    if !p.exists() {
                        return Err(format!("{}: no such file", p.display()));
                    }
                }
            }
        }
        other => return Err(format!("cargo fuzz {other:?}: not known to this test")),
    }
    Ok(Plan::Skip(
        "nightly cargo-fuzz: the fuzzing stage (.ci/fuzz.sh) fuzzes every target, bounded".into(),
    ))
}

/// Every documented command with its plan; every problem found.
fn plan() -> (Vec<(DocCommand, Plan)>, Vec<String>) {
    let mut out = Vec::new();
    let mut problems = Vec::new();
    for file in manuals() {
        let text = read(&file).expect("a manual");
        match commands(&file, &text) {
            Ok(cs) => {
                for c in cs {
                    match check(&c) {
                        Ok(p) => out.push((c, p)),
                        Err(e) => problems.push(format!("{}: `{}`: {e}", c.at, c.text)),
                    }
                }
            }
            Err(e) => problems.push(e),
        }
    }
    (out, problems)
}

#[test]
fn documented_commands_parse() {
    let (plan, problems) = plan();
    for (c, p) in &plan {
        println!("{}: {:?}: {}", c.at, p, c.text);
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    // The manuals show commands of every kind this test knows.
    assert!(plan.len() >= 40, "{} commands", plan.len());
    for kind in [Plan::Run, Plan::Qemu] {
        assert!(plan.iter().any(|(_, p)| *p == kind), "{kind:?}");
    }
    assert!(plan.iter().any(|(_, p)| matches!(p, Plan::Board(_))));
    // Among README's, the two that once needed --log and --json.
    for want in [["hil", "--compare"], ["gap", "--report"]] {
        assert!(
            plan.iter().any(|(c, _)| {
                c.at.starts_with("README.md")
                    && c.host_sim_args()
                        .is_some_and(|a| a[0] == want[0] && a.iter().any(|x| x == want[1]))
            }),
            "{want:?}"
        );
    }
}

/// The rules' own cases.
#[test]
fn the_rules_catch_wrong_commands() {
    let cmd = |text: &str, context: &str| DocCommand {
        at: "t.md:1".into(),
        text: text.into(),
        context: context.into(),
        dir: String::new(),
    };
    let bad = [
        "cargo run --release -p host-sim -- hil --qemu --no-such-option",
        "cargo run --release -p host-sim -- console --port /dev/ttyUSB0",
        "cargo test -p dca-tests --test no_such_test",
        "cargo test -p no-such-package",
        "cargo test -p dca-tests --test fuzz_corpus no_such_name",
        "cargo no-such-alias",
        "python3 no/such/script.py",
        "cargo +nightly fuzz run -O no_such_target",
        "make all",
    ];
    for b in bad {
        assert!(check(&cmd(b, "")).is_err(), "{b}");
    }
    assert_eq!(
        check(&cmd(
            "cargo run --release -p host-sim -- hil --port /dev/ttyACM0 --console /dev/ttyUSB0 --scenario step",
            "With a board on the bench:"
        )),
        Ok(Plan::Board(
            ["hil", "--qemu", "--scenario", "step"].map(String::from).to_vec()
        ))
    );
    let md = "Text\n\n```\ncargo run --release -p host-sim -- run\n```\n";
    assert!(commands("t.md", md).is_err());
    let md = "Text\n\n```sh\n# one\ncargo fw   # a comment\ncargo run --release -p host-sim -- run \\\n    --scenario step --log a.csv\n```\n";
    let cs = commands("t.md", md).unwrap();
    assert_eq!(cs.len(), 2);
    assert_eq!(cs[0].text, "cargo fw");
    assert_eq!(
        cs[1].text,
        "cargo run --release -p host-sim -- run --scenario step --log a.csv"
    );
    assert_eq!(cs[1].at, "t.md:6");
}

/// A file a documented command reads that the manuals assume the reader has.
struct Fixture {
    /// Where the command looks for it.
    path: &'static str,
    /// The stage that makes it.
    qemu: bool,
    /// How: a TOML block of the manuals whose first line is `# <name>`, or
    /// the arguments of a host-sim command.
    make: Make,
}

enum Make {
    Block(&'static str),
    HostSim(&'static str),
}

const FIXTURES: [Fixture; 6] = [
    Fixture { path: "my-test.toml", qemu: false, make: Make::Block("my-test.toml") },
    Fixture { path: "my-gains.toml", qemu: false, make: Make::Block("my-gains.toml") },
    Fixture { path: "my-rig.toml", qemu: false, make: Make::Block("my-rig.toml") },
    // A rig's recorded runs: simulated ones with a leaky seal.
    Fixture {
        path: "rig-run1.csv",
        qemu: false,
        make: Make::HostSim("run --scenario stepload --controller mpc-eso --sensors realistic --effect leakage --seed 1 --log rig-run1.csv"),
    },
    Fixture {
        path: "rig-run2.csv",
        qemu: false,
        make: Make::HostSim("run --scenario step --controller mpc-eso --sensors realistic --effect leakage --seed 2 --log rig-run2.csv"),
    },
    Fixture {
        path: "rig-run3.csv",
        qemu: false,
        make: Make::HostSim("run --scenario sineload --controller pid --sensors realistic --effect leakage --seed 3 --log rig-run3.csv"),
    },
];

/// The TOML block of the manuals whose first line is the comment `# name`
/// (possibly followed by more words).
fn toml_block(name: &str) -> Option<String> {
    manuals().into_iter().find_map(|f| {
        let text = read(&f).ok()?;
        blocks(&f, &text).into_iter().find_map(|b| {
            let first = b.lines.first()?.1.trim().to_string();
            let named = first
                .strip_prefix("# ")
                .is_some_and(|r| r.split([' ', ',']).next() == Some(name));
            (b.lang == "toml" && named).then(|| {
                let indent = b.lines[0].1.len() - b.lines[0].1.trim_start().len();
                b.lines
                    .iter()
                    .map(|l| l.1.get(indent..).unwrap_or(l.1.trim_start()))
                    .collect::<Vec<_>>()
                    .join("\n")
                    + "\n"
            })
        })
    })
}

/// Run `text` with bash in `dir`; its time, or why it failed.
fn run_shell(dir: &Path, text: &str, limit: Duration) -> Result<Duration, String> {
    let t0 = Instant::now();
    let mut child = Command::new("bash")
        .args(["-c", text])
        .current_dir(dir)
        .stdin(Stdio::null())
        .spawn()
        .map_err(|e| format!("bash: {e}"))?;
    loop {
        if let Some(st) = child.try_wait().map_err(|e| e.to_string())? {
            return if st.success() {
                Ok(t0.elapsed())
            } else {
                Err(format!("{st} after {:.0} s", t0.elapsed().as_secs_f64()))
            };
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            return Err(format!(
                "still running after {} s: stopped",
                limit.as_secs()
            ));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The scratch directory the commands run in: the repository's folders
/// linked in (docs/scripts/move.txt reads as written), its own `out/`.
fn scratch() -> PathBuf {
    let dir = root().join("target/doc-commands");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("target/doc-commands");
    for e in std::fs::read_dir(root())
        .expect("root")
        .filter_map(|e| e.ok())
    {
        let name = e.file_name().to_string_lossy().into_owned();
        // Folders only, not the build's or the outputs' (nor .cargo: cargo
        // would read its configuration twice, from here and from the root).
        let linked = e.path().is_dir()
            && !name.starts_with('.')
            && !["target", "out"].contains(&name.as_str());
        if linked {
            #[cfg(unix)]
            std::os::unix::fs::symlink(e.path(), dir.join(&name)).expect("symlink");
        }
    }
    dir
}

#[test]
#[ignore = "runs the manuals' commands end to end (minutes): CI's documented-commands stage (DCA_DOCS_RUN=host) and firmware stage (DCA_DOCS_RUN=qemu)"]
fn documented_commands_run() {
    let qemu = match std::env::var("DCA_DOCS_RUN").as_deref() {
        Ok("host") => false,
        Ok("qemu") => true,
        _ => panic!("set DCA_DOCS_RUN=host or DCA_DOCS_RUN=qemu"),
    };
    let (plan, problems) = plan();
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    let dir = scratch();
    let limit = Duration::from_secs(20 * 60);
    let mut failures = Vec::new();
    let mut log = Vec::new();
    let mut run = |at: &str, text: &str, failures: &mut Vec<String>| {
        eprintln!("\n== {at}: {text}");
        match run_shell(&dir, text, limit) {
            Ok(t) => log.push(format!("{:7.1} s  {at}: {text}", t.as_secs_f64())),
            Err(e) => failures.push(format!("{at}: `{text}`: {e}")),
        }
    };
    // The fixtures of this stage.
    let host_sim = "cargo run --release -p host-sim --";
    for f in FIXTURES.iter().filter(|f| f.qemu == qemu) {
        match &f.make {
            Make::Block(name) => {
                let text = toml_block(name).unwrap_or_else(|| panic!("no TOML block `# {name}`"));
                std::fs::write(dir.join(f.path), text).expect("fixture");
            }
            Make::HostSim(args) => {
                let _ = std::fs::create_dir_all(dir.join("out"));
                run("fixture", &format!("{host_sim} {args}"), &mut failures);
            }
        }
    }
    // Each command once, in the manuals' order; what reads a board's
    // capture waits for the QEMU stage.
    let mut seen = BTreeSet::new();
    let mut from_board: BTreeSet<String> = BTreeSet::new();
    let mut skipped = Vec::new();
    for (c, p) in &plan {
        let args = c.host_sim_args().unwrap_or_default();
        let reads_board = values_of(&args, &INPUTS)
            .iter()
            .any(|v| from_board.contains(*v));
        let text = match p {
            Plan::Board(emulated) => {
                from_board.extend(values_of(&args, &OUTPUTS).iter().map(|s| s.to_string()));
                qemu.then(|| format!("{host_sim} {}", emulated.join(" ")))
            }
            Plan::Qemu => {
                from_board.extend(values_of(&args, &OUTPUTS).iter().map(|s| s.to_string()));
                qemu.then(|| c.text.clone())
            }
            Plan::Run if reads_board => qemu.then(|| c.text.clone()),
            Plan::Run => (!qemu).then(|| c.text.clone()),
            Plan::Skip(why) => {
                skipped.push(format!("{}: `{}`: {why}", c.at, c.text));
                None
            }
        };
        let Some(text) = text else { continue };
        if !seen.insert(text.clone()) {
            continue;
        }
        if !c.dir.is_empty() {
            failures.push(format!("{}: runs in {}: not supported here", c.at, c.dir));
            continue;
        }
        let _ = std::fs::create_dir_all(dir.join("out"));
        run(&c.at, &text, &mut failures);
    }
    eprintln!(
        "\n== documented commands ({}):",
        if qemu { "qemu" } else { "host" }
    );
    for l in &log {
        eprintln!("{l}");
    }
    if !qemu {
        eprintln!("\nnot run here:");
        for s in &skipped {
            eprintln!("  {s}");
        }
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

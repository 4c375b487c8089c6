//! `host-sim console`: the board's console from a terminal (docs/interfaces.md
//! section 5).
//!
//! * Interactive (the default): line editing and history (rustyline); each
//!   line is sent and its reply shown; the telemetry stream is shown as it
//!   comes unless it is being captured; Ctrl-D ends the session.
//! * `--script FILE`: the lines of FILE one by one, each waiting for its
//!   reply; blank lines and `#` comments are skipped, `sleep S` pauses S
//!   seconds. Fails (non-zero exit) when any reply was an error or did not
//!   come in time.
//! * `--capture OUT.csv`: the telemetry stream (after `telemetry on`, until
//!   `telemetry off` or the end of the session) written as a run log; see
//!   [`super::capture`] for its time step. Where the session issues `dump`,
//!   OUT.csv is the board's record instead (the last dump), a 1 ms run log
//!   ([`super::record`]); a dump with a lost or damaged frame fails the
//!   session.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::capture::Capture;
use super::console::{ConsoleClient, LineKind, Reply, Sink, CONSOLE_BAUD};
use super::port::SerialLink;
use super::qemu::{Emulator, QemuOptions};
use super::record::BoardRecord;
use super::BoardError;

/// One step of a console script.
#[derive(Clone, Debug, PartialEq)]
pub enum Step {
    /// Send this line and wait for its reply.
    Send(String),
    /// Pause, s.
    Sleep(f64),
}

/// A console script line that is not a command or a `sleep`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ScriptError {
    /// `sleep` without a number of seconds in [0, 3600].
    #[error("{file}:{line}: expected `sleep S` with S in seconds, 0 to 3600: `{text}`")]
    Sleep {
        /// The script.
        file: String,
        /// 1-based line.
        line: usize,
        /// The line (trimmed).
        text: String,
    },
    /// Not printable ASCII, or longer than a console line.
    #[error(
        "{file}:{line}: a console line is printable ASCII of at most {} characters",
        dca_app::console::MAX_LINE
    )]
    Line {
        /// The script.
        file: String,
        /// 1-based line.
        line: usize,
    },
}

/// Read a script: one command per line; blank lines and lines starting with
/// `#` skipped; `sleep S` (S seconds, 0 to 3600) pauses. Errors name the file
/// and line.
pub fn parse_script(text: &str, file: &str) -> Result<Vec<Step>, ScriptError> {
    let mut steps = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut words = line.split_ascii_whitespace();
        if words.next() == Some("sleep") {
            let s = match (words.next().map(str::parse::<f64>), words.next()) {
                (Some(Ok(s)), None) if (0.0..=3600.0).contains(&s) => s,
                _ => {
                    return Err(ScriptError::Sleep {
                        file: file.to_string(),
                        line: i + 1,
                        text: line.to_string(),
                    })
                }
            };
            steps.push(Step::Sleep(s));
            continue;
        }
        if line.len() > dca_app::console::MAX_LINE
            || !line.bytes().all(|b| (0x20..0x7f).contains(&b))
        {
            return Err(ScriptError::Line {
                file: file.to_string(),
                line: i + 1,
            });
        }
        steps.push(Step::Send(line.to_string()));
    }
    Ok(steps)
}

/// Where the console is.
#[derive(Clone, Debug)]
pub enum Target {
    /// A serial device at a baud rate.
    Port(String, u32),
    /// The emulated firmware.
    Qemu(PathBuf, QemuOptions),
}

/// A console session's settings.
#[derive(Clone, Debug)]
pub struct SessionOptions {
    /// The board or the emulator.
    pub target: Target,
    /// Script steps (`None`: interactive).
    pub script: Option<Vec<Step>>,
    /// Where to write the captured telemetry.
    pub capture: Option<PathBuf>,
    /// Longest wait for a reply.
    pub timeout: Duration,
    /// The live view ([`super::scope`]) instead of the plain interactive
    /// console (not with a script).
    pub scope: bool,
}

/// How a session ended.
#[derive(Clone, Debug, Default)]
pub struct SessionReport {
    /// Lines sent.
    pub sent: usize,
    /// Replies that were errors.
    pub errors: usize,
    /// Rows written to the capture.
    pub rows: usize,
    /// Time step of the capture, s.
    pub step_s: Option<f64>,
    /// Why the capture is incomplete or missing, if it is.
    pub capture_problem: Option<String>,
    /// The last `dump`: the record read, or why it could not be.
    pub dump: Option<Result<BoardRecord, String>>,
}

impl SessionReport {
    /// Count one reply to `line` and show it (text; a dump's frames are
    /// read, not shown).
    fn reply(&mut self, line: &str, reply: &Reply) {
        print!("{}", reply.text());
        if let Some(note) = self.count(line, reply) {
            eprintln!("{note}");
        }
    }

    /// Count one reply to `line`; a reply to `dump` is read as the board's
    /// record (see [`BoardRecord::from_reply`]). A note on the dump, if any.
    pub fn count(&mut self, line: &str, reply: &Reply) -> Option<String> {
        self.sent += 1;
        if !reply.is_ok() {
            self.errors += 1;
        }
        let is_dump = line.split_ascii_whitespace().next() == Some("dump");
        if !(is_dump && reply.is_ok()) {
            return None;
        }
        let r = BoardRecord::from_reply(reply).map_err(|e| e.to_string());
        let note = match &r {
            Ok(rec) => format!("record of {} rows (1 ms) received", rec.rows.len()),
            Err(e) => e.clone(),
        };
        self.dump = Some(r);
        Some(note)
    }
}

impl SessionReport {
    /// Every reply was `ok` and the capture (if asked for) is whole.
    pub fn success(&self) -> bool {
        self.errors == 0 && self.capture_problem.is_none()
    }
}

/// The stream sink: into the capture, or shown.
fn sink(capture: Option<Arc<Mutex<Capture>>>, mut show: impl FnMut(&str) + Send + 'static) -> Sink {
    Box::new(move |kind, line| match (&capture, kind) {
        (Some(c), LineKind::Stream) => {
            if let Ok(mut c) = c.lock() {
                c.line(line);
            }
        }
        _ => show(line),
    })
}

/// Run a session (see the module documentation).
pub fn run_session(opts: &SessionOptions) -> Result<SessionReport, BoardError> {
    let (emulator, port, baud) = match &opts.target {
        Target::Port(p, b) => (None, p.clone(), *b),
        Target::Qemu(elf, q) => {
            let e = Emulator::start(elf, q)?;
            let tty = e.console_tty.clone();
            (Some(e), tty, CONSOLE_BAUD)
        }
    };
    let link = SerialLink::open(&port, baud, Duration::from_millis(50))?;
    let mut client = ConsoleClient::connect(link, opts.timeout)?;
    eprintln!("connected to the console on {port} ({baud} baud)");
    let capture = opts
        .capture
        .as_ref()
        .map(|_| Arc::new(Mutex::new(Capture::new())));
    let mut report = match &opts.script {
        Some(steps) => {
            client.set_sink(Some(sink(capture.clone(), |l| println!("{l}"))));
            run_script(&mut client, steps)?
        }
        None if opts.scope => {
            let mut report = SessionReport::default();
            super::scope::run_scope(&mut client, capture.clone(), |line, reply| {
                report.count(line, reply)
            })?;
            report
        }
        None => run_interactive(&mut client, capture.clone())?,
    };
    client.set_sink(None);
    match (&opts.capture, &capture, report.dump.take()) {
        (Some(path), _, Some(dump)) => finish_record(dump, path, &port, &mut report),
        (Some(path), Some(c), None) => {
            let c = c.lock().map(|c| c.clone()).unwrap_or_default();
            finish_capture(&c, path, &port, &mut report);
        }
        (None, _, Some(Err(e))) => report.capture_problem = Some(e),
        _ => {}
    }
    if let Some(e) = emulator {
        e.quit(&mut client)?;
    }
    Ok(report)
}

/// Write the session's last dump as the capture.
fn finish_record(
    dump: Result<BoardRecord, String>,
    path: &Path,
    port: &str,
    report: &mut SessionReport,
) {
    let rec = match dump {
        Ok(r) => r,
        Err(e) => {
            report.capture_problem = Some(format!("the dump is not whole: {e}"));
            return;
        }
    };
    if let Err(e) = rec.write(path, &[("port", port.to_string())]) {
        report.capture_problem = Some(format!("{}: {e}", path.display()));
        return;
    }
    report.rows = rec.rows.len();
    report.step_s = Some(dca_app::record::RECORD_DT_S);
    eprintln!(
        "the board's record: {} rows, step 0.001 s -> {}",
        rec.rows.len(),
        path.display()
    );
}

fn finish_capture(c: &Capture, path: &Path, port: &str, report: &mut SessionReport) {
    report.rows = c.rows();
    report.step_s = c.step_s();
    if c.streams() > 1 {
        eprintln!(
            "note: {} telemetry streams; the capture holds the last",
            c.streams()
        );
    }
    if let Err(e) = c.write(path, &[("port", port.to_string())]) {
        report.capture_problem = Some(format!("{}: {e}", path.display()));
        return;
    }
    if let Some((a, b)) = c.gap() {
        report.capture_problem = Some(format!(
            "telemetry rows between t = {a:.3} s and {b:.3} s were lost (the board could not \
             send them in time; use a larger decimation): {} holds the {} rows before the gap",
            path.display(),
            c.rows()
        ));
    }
    eprintln!(
        "captured {} rows ({}) -> {}",
        c.rows(),
        c.step_s()
            .map_or("one row".into(), |s| format!("step {s} s")),
        path.display()
    );
}

fn run_script(client: &mut ConsoleClient, steps: &[Step]) -> Result<SessionReport, BoardError> {
    let mut report = SessionReport::default();
    for step in steps {
        match step {
            Step::Sleep(s) => std::thread::sleep(Duration::from_secs_f64(*s)),
            Step::Send(line) => {
                println!("> {line}");
                let reply = client.command(line)?;
                report.reply(line, &reply);
            }
        }
    }
    Ok(report)
}

fn history_path() -> Option<PathBuf> {
    std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".dca-console-history"))
}

fn run_interactive(
    client: &mut ConsoleClient,
    capture: Option<Arc<Mutex<Capture>>>,
) -> Result<SessionReport, BoardError> {
    use rustyline::error::ReadlineError;
    use rustyline::ExternalPrinter as _;
    let readline_err = |e: ReadlineError| BoardError::Io {
        port: "terminal".into(),
        error: std::io::Error::other(e),
    };
    let mut rl = rustyline::DefaultEditor::new().map_err(readline_err)?;
    let history = history_path();
    if let Some(h) = &history {
        let _ = rl.load_history(h);
    }
    // Lines not asked for are printed above the prompt.
    match rl.create_external_printer() {
        Ok(mut p) => client.set_sink(Some(sink(capture, move |l| {
            let _ = p.print(format!("{l}\n"));
        }))),
        Err(_) => client.set_sink(Some(sink(capture, |l| println!("{l}")))),
    }
    eprintln!("type console commands ('help'); Ctrl-D ends the session");
    let mut report = SessionReport::default();
    loop {
        let line = match rl.readline("dca> ") {
            Ok(l) => l,
            Err(ReadlineError::Eof) => break,
            Err(ReadlineError::Interrupted) => continue,
            Err(e) => return Err(readline_err(e)),
        };
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let _ = rl.add_history_entry(line);
        match client.command(line) {
            Ok(reply) => report.reply(line, &reply),
            Err(e @ BoardError::NoReply { .. }) => {
                eprintln!("{e}");
                report.errors += 1;
            }
            Err(e) => return Err(e),
        }
    }
    if let Some(h) = &history {
        let _ = rl.save_history(h);
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scripts_skip_comments_and_read_sleeps() {
        let s = parse_script("# set-up\n\narm\nsleep 0.5\n  goto 20  \n", "s.txt").unwrap();
        assert_eq!(
            s,
            vec![
                Step::Send("arm".into()),
                Step::Sleep(0.5),
                Step::Send("goto 20".into())
            ]
        );
        for bad in ["sleep", "sleep x", "sleep -1", "sleep 1 2", "sleep inf"] {
            let e = parse_script(&format!("arm\n{bad}\n"), "s.txt")
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("s.txt:2:"), "{e}");
        }
        let long = "x".repeat(81);
        assert!(parse_script(&long, "s.txt")
            .unwrap_err()
            .to_string()
            .starts_with("s.txt:1:"));
        assert!(parse_script("g\u{e9}t\n", "s.txt").is_err());
    }
}

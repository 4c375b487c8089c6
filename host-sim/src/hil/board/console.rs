//! The host side of the board's line console (USART1, 115 200 baud).
//!
//! A reader thread splits what the board sends into lines and sorts them:
//! replies (the answer lines of a command and its final `ok` or
//! `error: <reason>`) go to the command that waits for them; the telemetry
//! stream (`#` metadata, the `t_s,...` header and rows) and notices (the
//! boot banner) go to a [`Sink`]. Because the board answers every line
//! exactly once and in order, one reply per command keeps the two sides in
//! step.
//!
//! # Start-up
//! Nothing the port held before is trusted: the banner may be long gone (a
//! board that booted earlier, or a pseudo-terminal that dropped it before it
//! was opened), a partial line may sit in the board's editor, echo may be on.
//! [`ConsoleClient::connect`] sends a line end (ending any partial line) and
//! `ping <token>` with a fresh token, and skips everything up to `pong <token>`
//! and its `ok`, retrying with a new token every second; then it turns echo
//! off. A port that gives no `pong` within [`HANDSHAKE`] is an error naming the
//! port, its baud rate and what was tried.
//!
//! # Binary frames
//! The reply to `dump` is a line `dump rows=N frames=F`, then F binary frames
//! (dca_app::record, 0x00-delimited), then `ok`. The reader switches to
//! frames right after that line and back to lines after the F-th delimiter;
//! the frames come with the reply ([`Reply::frames`]), unchecked (the caller
//! decodes them). While frames arrive the reply's deadline moves on with
//! them, so a dump of any length needs only that bytes keep coming.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::port::SerialLink;
use super::BoardError;

/// The console's baud rate.
pub const CONSOLE_BAUD: u32 = 115_200;

/// Longest wait for the first `pong`.
pub const HANDSHAKE: Duration = Duration::from_secs(5);

/// What a line from the board is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineKind {
    /// Part of a command's reply.
    Reply,
    /// Telemetry: `#` metadata, the run-log header or a row.
    Stream,
    /// A notice not asked for (the boot banner and its notes).
    Notice,
}

/// Sort one line (without its line end). Replies never start with a digit,
/// `#` or `t_s,`; telemetry rows start with their time stamp.
pub fn classify(line: &str) -> LineKind {
    if line.starts_with('#')
        || line.starts_with("t_s,")
        || line.starts_with(|c: char| c.is_ascii_digit())
    {
        LineKind::Stream
    } else if line.starts_with("dca-firmware ") || line.starts_with("note: ") {
        LineKind::Notice
    } else {
        LineKind::Reply
    }
}

/// Whether `line` ends a reply.
pub fn is_reply_end(line: &str) -> bool {
    line == "ok" || line.starts_with("error:")
}

/// The number of binary frames that follow a reply line, if it announces
/// them (`dump rows=N frames=F`).
pub fn frames_announced(line: &str) -> Option<usize> {
    let rest = line.strip_prefix("dump rows=")?;
    let (_, f) = rest.split_once(" frames=")?;
    f.parse().ok()
}

/// A complete reply.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Reply {
    /// The answer lines before the last one.
    pub lines: Vec<String>,
    /// `ok` or `error: <reason>`.
    pub last: String,
    /// Binary frames that came with the reply (their bodies, without the
    /// `0x00` delimiter).
    pub frames: Vec<Vec<u8>>,
}

impl Reply {
    /// The reply ended with `ok`.
    pub fn is_ok(&self) -> bool {
        self.last == "ok"
    }

    /// All lines, each ended by a newline.
    pub fn text(&self) -> String {
        let mut t = String::new();
        for l in self.lines.iter().chain([&self.last]) {
            t.push_str(l);
            t.push('\n');
        }
        t
    }
}

/// Where the lines that are not replies go (called on the reader thread).
pub type Sink = Box<dyn FnMut(LineKind, &str) + Send>;

/// What the reader thread passes to a waiting command.
enum Msg {
    Line(String),
    Frame(Vec<u8>),
}

/// A console connection with its reader thread.
pub struct ConsoleClient {
    tx: SerialLink,
    replies: Receiver<Result<Msg, BoardError>>,
    sink: Arc<Mutex<Option<Sink>>>,
    stop: Arc<AtomicBool>,
    reader: Option<JoinHandle<()>>,
    timeout: Duration,
}

impl ConsoleClient {
    /// Take over `link` (the console port), find the start of the board's
    /// replies (see the module documentation) and turn echo off. Replies are
    /// awaited for at most `timeout`.
    pub fn connect(link: SerialLink, timeout: Duration) -> Result<Self, BoardError> {
        let mut c = Self::start(link, timeout)?;
        c.handshake()?;
        c.must("echo off")?;
        Ok(c)
    }

    fn start(mut link: SerialLink, timeout: Duration) -> Result<Self, BoardError> {
        link.set_timeout(Duration::from_millis(50))?;
        let mut rx = link.try_clone()?;
        let (reply_tx, replies) = mpsc::channel();
        let sink: Arc<Mutex<Option<Sink>>> = Arc::new(Mutex::new(None));
        let stop = Arc::new(AtomicBool::new(false));
        let (sink2, stop2) = (Arc::clone(&sink), Arc::clone(&stop));
        let reader = std::thread::Builder::new()
            .name("console-reader".into())
            .spawn(move || {
                let mut pending: Vec<u8> = Vec::new();
                let mut buf = [0u8; 1024];
                // Binary frames still to come after a `dump` line.
                let mut frames_due = 0usize;
                while !stop2.load(Ordering::Relaxed) {
                    let n = match rx.read_some(&mut buf) {
                        Ok(n) => n,
                        Err(e) => {
                            let _ = reply_tx.send(Err(e));
                            return;
                        }
                    };
                    pending.extend_from_slice(&buf[..n]);
                    loop {
                        if frames_due > 0 {
                            let Some(i) = pending.iter().position(|b| *b == 0) else {
                                break;
                            };
                            let mut body: Vec<u8> = pending.drain(..=i).collect();
                            body.pop();
                            frames_due -= 1;
                            if reply_tx.send(Ok(Msg::Frame(body))).is_err() {
                                return;
                            }
                            continue;
                        }
                        let Some(i) = pending.iter().position(|b| *b == b'\n') else {
                            break;
                        };
                        let raw: Vec<u8> = pending.drain(..=i).collect();
                        let text = String::from_utf8_lossy(&raw);
                        let line = text.trim_end_matches(['\r', '\n']);
                        if line.is_empty() {
                            continue;
                        }
                        match classify(line) {
                            LineKind::Reply => {
                                frames_due = frames_announced(line).unwrap_or(0);
                                if reply_tx.send(Ok(Msg::Line(line.to_string()))).is_err() {
                                    return;
                                }
                            }
                            kind => {
                                if let Ok(mut s) = sink2.lock() {
                                    if let Some(f) = s.as_mut() {
                                        f(kind, line);
                                    }
                                }
                            }
                        }
                    }
                }
            })
            .map_err(|e| BoardError::Io {
                port: link.name().to_string(),
                error: e,
            })?;
        Ok(Self {
            tx: link,
            replies,
            sink,
            stop,
            reader: Some(reader),
            timeout,
        })
    }

    /// The port's device path.
    pub fn port(&self) -> &str {
        self.tx.name()
    }

    /// Send stream lines and notices to `sink` from now on (`None`: drop
    /// them).
    pub fn set_sink(&self, sink: Option<Sink>) {
        if let Ok(mut s) = self.sink.lock() {
            *s = sink;
        }
    }

    fn handshake(&mut self) -> Result<(), BoardError> {
        let start = Instant::now();
        // A token no earlier session used: process id and wall-clock time.
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let base = std::process::id() ^ now;
        let mut tries = 0u32;
        while start.elapsed() < HANDSHAKE {
            tries += 1;
            let token = format!("dca{base:x}-{tries}");
            self.tx.send(format!("\r\nping {token}\r\n").as_bytes())?;
            let pong = format!("pong {token}");
            let until = (Instant::now() + Duration::from_secs(1)).min(start + HANDSHAKE);
            let mut seen = false;
            while let Some(line) = self.next_reply_line(until)? {
                if line == pong {
                    seen = true;
                } else if seen && line == "ok" {
                    return Ok(());
                }
            }
        }
        Err(BoardError::NoConsole {
            port: self.port().to_string(),
            baud: self.tx.baud(),
            secs: HANDSHAKE.as_secs_f64(),
            tries,
        })
    }

    /// The next reply line (frames skipped), or `None` once `until` has
    /// passed.
    fn next_reply_line(&mut self, until: Instant) -> Result<Option<String>, BoardError> {
        loop {
            match self.next_msg(until)? {
                Some(Msg::Line(l)) => return Ok(Some(l)),
                Some(Msg::Frame(_)) => {}
                None => return Ok(None),
            }
        }
    }

    /// The next line or frame of a reply, or `None` once `until` has passed.
    fn next_msg(&mut self, until: Instant) -> Result<Option<Msg>, BoardError> {
        let left = until.saturating_duration_since(Instant::now());
        match self.replies.recv_timeout(left) {
            Ok(Ok(m)) => Ok(Some(m)),
            Ok(Err(e)) => Err(e),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(BoardError::Closed {
                port: self.port().to_string(),
            }),
        }
    }

    /// Send one command line and wait for its whole reply.
    pub fn command(&mut self, line: &str) -> Result<Reply, BoardError> {
        self.tx.send(format!("{line}\r\n").as_bytes())?;
        let mut until = Instant::now() + self.timeout;
        let mut reply = Reply::default();
        loop {
            let l = match self.next_msg(until)? {
                Some(Msg::Line(l)) => l,
                Some(Msg::Frame(f)) => {
                    reply.frames.push(f);
                    // A long dump: the deadline follows the frames.
                    until = Instant::now() + self.timeout;
                    continue;
                }
                None => {
                    return Err(BoardError::NoReply {
                        port: self.port().to_string(),
                        command: line.to_string(),
                        secs: self.timeout.as_secs_f64(),
                    })
                }
            };
            if is_reply_end(&l) {
                reply.last = l;
                return Ok(reply);
            }
            reply.lines.push(l);
        }
    }

    /// Send a command that must succeed.
    pub fn must(&mut self, line: &str) -> Result<Reply, BoardError> {
        let r = self.command(line)?;
        if r.is_ok() {
            Ok(r)
        } else {
            Err(BoardError::Refused {
                command: line.to_string(),
                reply: r.last,
            })
        }
    }

    /// Send raw bytes (no line end added, no reply awaited).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<(), BoardError> {
        self.tx.send(bytes)
    }
}

impl Drop for ConsoleClient {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_sorted_into_replies_stream_and_notices() {
        for l in [
            "ok",
            "error: unknown command (try 'help')",
            "pong x",
            "state=idle faults=none",
            "eso.beta1 = 30",
            "mpc-eso",
            "(settings, controller, preset, hil: only while idle)",
        ] {
            assert_eq!(classify(l), LineKind::Reply, "{l}");
        }
        for l in [
            "# dca-log v1",
            "t_s,ref_m,vcmd_mps",
            "0.000,0.0000000,0.0000000,0.00000000,0.00000000,1000000.0,1000000.0,0.00,1,0",
            "12.340,0.05",
        ] {
            assert_eq!(classify(l), LineKind::Stream, "{l}");
        }
        assert_eq!(
            classify("dca-firmware 0.1.0 ready; type 'help'"),
            LineKind::Notice
        );
        assert!(is_reply_end("ok") && is_reply_end("error: x") && !is_reply_end("okay"));
        assert_eq!(frames_announced("dump rows=10 frames=5"), Some(5));
        for l in [
            "dump rows=10",
            "dump frames=5",
            "record=done rows=3 of 3",
            "ok",
        ] {
            assert_eq!(frames_announced(l), None, "{l}");
        }
    }
}

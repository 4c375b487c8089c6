//! The emulated firmware: the `qemu` build of dca-firmware on QEMU's
//! `netduinoplus2`, its two USARTs on pseudo-terminals (`-serial pty`), so
//! that the host reaches it exactly as it reaches a board over USB-serial
//! ttys.
//!
//! QEMU names the ptys on its standard output ("char device redirected to
//! /dev/pts/N (label serialK)"); the rest of that output is the firmware's
//! defmt log over semihosting, kept in a file when asked for.
//!
//! `-icount shift=3,sleep=on`: instruction-driven virtual time while the CPU
//! runs (deterministic control ticks and deadline checks), real time while it
//! sleeps, so that the firmware's HIL timeout measures the host's real
//! response time instead of racing ahead of it.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use super::console::ConsoleClient;
use super::BoardError;

/// How to start QEMU.
#[derive(Clone, Debug)]
pub struct QemuOptions {
    /// The emulator binary.
    pub qemu: PathBuf,
    /// Longest wait for QEMU to start and for any reply.
    pub timeout: Duration,
    /// Where the firmware's defmt frames (QEMU's standard output after the
    /// pty names) go; discarded if `None`.
    pub defmt_out: Option<PathBuf>,
}

impl Default for QemuOptions {
    fn default() -> Self {
        Self {
            qemu: PathBuf::from("qemu-system-arm"),
            timeout: Duration::from_secs(10),
            defmt_out: None,
        }
    }
}

/// How to install the emulator, for error messages.
pub const QEMU_INSTALL: &str = "install QEMU's Arm system emulator: `sudo apt-get install \
     qemu-system-arm` (Debian, Ubuntu), `sudo dnf install qemu-system-arm` (Fedora) or `brew \
     install qemu` (macOS)";

/// The emulator binary `qemu` as it will be started: a path is checked as
/// given, a bare name is looked up on `PATH`. Called before anything is built,
/// so that a missing QEMU is reported at once, with how to install it.
pub fn find_qemu(qemu: &Path) -> Result<PathBuf, BoardError> {
    let runnable = |p: &Path| {
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            p.metadata()
                .is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
        }
        #[cfg(not(unix))]
        {
            p.is_file()
        }
    };
    let found = if qemu.components().count() > 1 {
        runnable(qemu).then(|| qemu.to_path_buf())
    } else {
        std::env::var_os("PATH").and_then(|path| {
            std::env::split_paths(&path)
                .map(|dir| dir.join(qemu))
                .find(|p| runnable(p))
        })
    };
    found.ok_or_else(|| {
        BoardError::Emulator(format!(
            "{} not found{}: the emulated board needs it; {QEMU_INSTALL} (or give --port for a \
             board)",
            qemu.display(),
            if qemu.components().count() > 1 {
                ""
            } else {
                " on PATH"
            }
        ))
    })
}

/// Why the emulated firmware's ELF could not be built.
#[derive(Debug, thiserror::Error)]
pub enum ElfError {
    /// Cargo could not be started.
    #[error("cargo fw-qemu: {0}")]
    Spawn(std::io::Error),
    /// The build failed.
    #[error(
        "cargo fw-qemu failed ({0}); install the target with `rustup target add thumbv7em-none-eabihf`"
    )]
    Build(std::process::ExitStatus),
}

/// The emulated firmware's ELF: `elf`, or the workspace's `cargo fw-qemu`
/// build, built first (saying so on standard error) when it is missing.
pub fn firmware_elf(elf: Option<PathBuf>) -> Result<PathBuf, ElfError> {
    if let Some(e) = elf {
        return Ok(e);
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let path = root.join("target/qemu/thumbv7em-none-eabihf/firmware/dca-firmware");
    if !path.exists() {
        eprintln!("building the emulated firmware (cargo fw-qemu) ...");
        let status = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
            .current_dir(&root)
            .args(["fw-qemu"])
            .status()
            .map_err(ElfError::Spawn)?;
        if !status.success() {
            return Err(ElfError::Build(status));
        }
    }
    Ok(path)
}

/// A running emulated firmware.
pub struct Emulator {
    child: Child,
    /// The console's tty (USART1).
    pub console_tty: String,
    /// The HIL link's tty (USART2).
    pub hil_tty: String,
    timeout: Duration,
}

/// The pty of a "char device redirected to /dev/pts/N (label serialK)" line.
fn pty_of(line: &str) -> Option<(usize, String)> {
    let rest = line.strip_prefix("char device redirected to ")?;
    let (path, label) = rest.split_once(" (label serial")?;
    let k = label.strip_suffix(')')?.parse().ok()?;
    Some((k, path.to_string()))
}

impl Emulator {
    /// Start QEMU on `elf` with both USARTs on ptys; returns once QEMU has
    /// named them.
    pub fn start(elf: &Path, opts: &QemuOptions) -> Result<Self, BoardError> {
        let qemu = find_qemu(&opts.qemu)?;
        if !elf.exists() {
            return Err(BoardError::Emulator(format!(
                "no firmware ELF at {} (build it with `cargo fw-qemu`)",
                elf.display()
            )));
        }
        let mut child = Command::new(&qemu)
            .args([
                "-machine",
                "netduinoplus2",
                "-nographic",
                "-monitor",
                "none",
            ])
            .args(["-semihosting-config", "enable=on,target=native"])
            .args(["-icount", "shift=3,sleep=on"])
            .args(["-serial", "pty", "-serial", "pty"])
            .arg("-kernel")
            .arg(elf)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| BoardError::Emulator(format!("cannot start {}: {e}", qemu.display())))?;
        let stdout = child.stdout.take().expect("piped");
        let (tx, rx) = mpsc::channel();
        let mut log: Box<dyn Write + Send> = match &opts.defmt_out {
            Some(p) => Box::new(
                std::fs::File::create(p)
                    .map_err(|e| BoardError::Emulator(format!("{}: {e}", p.display())))?,
            ),
            None => Box::new(std::io::sink()),
        };
        // Read the pty names, then keep draining (QEMU must never block on a
        // full pipe) into the defmt log.
        std::thread::spawn(move || {
            let mut r = BufReader::new(stdout);
            let mut found = 0;
            while found < 2 {
                let mut line = String::new();
                match r.read_line(&mut line) {
                    Ok(0) | Err(_) => return,
                    Ok(_) => {
                        if let Some(p) = pty_of(line.trim_end()) {
                            found += 1;
                            let _ = tx.send(p);
                        }
                    }
                }
            }
            let _ = std::io::copy(&mut r, &mut log);
        });
        let mut ptys: [Option<String>; 2] = [None, None];
        let until = Instant::now() + opts.timeout;
        while ptys.iter().any(Option::is_none) {
            let left = until.saturating_duration_since(Instant::now());
            match rx.recv_timeout(left) {
                Ok((k, p)) if k < 2 => ptys[k] = Some(p),
                Ok(_) => {}
                Err(_) => {
                    let _ = child.kill();
                    let mut err = String::new();
                    if let Some(mut e) = child.stderr.take() {
                        let _ = e.read_to_string(&mut err);
                    }
                    return Err(BoardError::Emulator(format!(
                        "QEMU named no ptys within {:.0} s: {}",
                        opts.timeout.as_secs_f64(),
                        err.trim()
                    )));
                }
            }
        }
        let [Some(console_tty), Some(hil_tty)] = ptys else {
            unreachable!("both set above")
        };
        Ok(Self {
            child,
            console_tty,
            hil_tty,
            timeout: opts.timeout,
        })
    }

    /// End the emulator with the console's `quit`; its exit status must be 0.
    ///
    /// The firmware answers `ok` and ends QEMU at once, so the pty may close
    /// before the `ok` arrives: the exit status is the answer, not the reply.
    pub fn quit(mut self, console: &mut ConsoleClient) -> Result<(), BoardError> {
        console.send_raw(b"quit\r\n")?;
        let until = Instant::now() + self.timeout;
        loop {
            match self.child.try_wait() {
                Ok(Some(status)) if status.success() => return Ok(()),
                Ok(Some(status)) => {
                    let mut err = String::new();
                    if let Some(mut e) = self.child.stderr.take() {
                        let _ = e.read_to_string(&mut err);
                    }
                    return Err(BoardError::Emulator(format!(
                        "QEMU exited with {status}: {}",
                        err.trim()
                    )));
                }
                Ok(None) if Instant::now() < until => std::thread::sleep(Duration::from_millis(10)),
                Ok(None) => {
                    return Err(BoardError::Emulator(
                        "QEMU did not exit after `quit`".into(),
                    ))
                }
                Err(e) => return Err(BoardError::Emulator(format!("QEMU: {e}"))),
            }
        }
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        // Only if still running (after `quit` it has exited): never leave one behind.
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn pty_lines_are_read() {
        assert_eq!(
            super::pty_of("char device redirected to /dev/pts/3 (label serial1)"),
            Some((1, "/dev/pts/3".into()))
        );
        assert_eq!(super::pty_of("something else"), None);
    }
}

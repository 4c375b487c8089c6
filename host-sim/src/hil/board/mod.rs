//! The host's side of a board: serial ports, the line console, telemetry
//! captures and the emulated firmware.
//!
//! * [`port`]: a serial port (a USB-serial tty of a board, or a pty of the
//!   emulated firmware) through the `serialport` crate;
//! * [`console`]: the console client: start-up handshake, one reply per
//!   command, the telemetry stream set apart;
//! * [`capture`]: a telemetry stream written as a run log;
//! * [`record`]: the board's own record (`dump`) read and written as a run log;
//! * [`qemu`]: the emulated firmware on QEMU with its USARTs on ptys;
//! * [`session`]: `host-sim console`, interactive or from a script;
//! * [`scope`]: `host-sim console --scope`, the live view in the terminal.

pub mod capture;
pub mod console;
pub mod port;
pub mod qemu;
pub mod record;
pub mod scope;
pub mod session;

/// What went wrong talking to a board.
#[derive(Debug, thiserror::Error)]
pub enum BoardError {
    /// The port could not be opened.
    #[error("{port}: cannot open: {error}")]
    Open {
        /// Device path.
        port: String,
        /// Why (shown in the message, not chained).
        error: serialport::Error,
    },
    /// Reading or writing failed.
    #[error("{port}: {error}")]
    Io {
        /// Device path.
        port: String,
        /// Why (shown in the message, not chained).
        error: std::io::Error,
    },
    /// The port closed.
    #[error("{port}: the port closed")]
    Closed {
        /// Device path.
        port: String,
    },
    /// The console never answered the start-up handshake.
    #[error(
        "no answer from a dca console on {port} at {baud} baud within {secs:.0} s \
         (sent `ping` {tries} times): is this the board's console port (USART1), \
         is the board powered and running dca-firmware?"
    )]
    NoConsole {
        /// Device path.
        port: String,
        /// Baud rate used.
        baud: u32,
        /// How long it waited, s.
        secs: f64,
        /// Pings sent.
        tries: u32,
    },
    /// A command got no complete reply in time.
    #[error("{port}: no reply to `{command}` within {secs:.1} s")]
    NoReply {
        /// Device path.
        port: String,
        /// The command sent.
        command: String,
        /// How long it waited, s.
        secs: f64,
    },
    /// The console answered a command that had to succeed with an error.
    #[error("the console refused `{command}`: {reply}")]
    Refused {
        /// The command sent.
        command: String,
        /// The final reply line.
        reply: String,
    },
    /// The emulator could not be started or ended badly.
    #[error("emulator: {0}")]
    Emulator(String),
}

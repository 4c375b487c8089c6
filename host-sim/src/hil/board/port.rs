//! Serial ports: a board's USB-serial ttys, or the pseudo-terminals of the
//! emulated firmware (QEMU `-serial pty`), opened the same way through the
//! `serialport` crate.

use std::io::{self, Read, Write};
use std::time::Duration;

use super::BoardError;

/// An open serial port, named after its device for error messages.
pub struct SerialLink {
    port: Box<dyn serialport::SerialPort>,
    name: String,
    baud: u32,
}

impl SerialLink {
    /// Open `path` at `baud` (8N1, raw), reads waiting at most `timeout`, and
    /// drop whatever the port had received before it was opened.
    pub fn open(path: &str, baud: u32, timeout: Duration) -> Result<Self, BoardError> {
        let port = serialport::new(path, baud)
            .timeout(timeout)
            .open()
            .map_err(|error| BoardError::Open {
                port: path.to_string(),
                error,
            })?;
        let link = Self {
            port,
            name: path.to_string(),
            baud,
        };
        link.clear_input()?;
        Ok(link)
    }

    /// The device path.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The baud rate it was opened at.
    pub fn baud(&self) -> u32 {
        self.baud
    }

    /// Drop received bytes not yet read.
    pub fn clear_input(&self) -> Result<(), BoardError> {
        self.port
            .clear(serialport::ClearBuffer::Input)
            .map_err(|e| self.io(io::Error::other(e)))
    }

    /// Set the read timeout.
    pub fn set_timeout(&mut self, t: Duration) -> Result<(), BoardError> {
        self.port.set_timeout(t).map_err(|e| BoardError::Io {
            port: self.name.clone(),
            error: io::Error::other(e),
        })
    }

    /// A second handle on the same port (for a reader thread).
    pub fn try_clone(&self) -> Result<Self, BoardError> {
        Ok(Self {
            port: self
                .port
                .try_clone()
                .map_err(|e| self.io(io::Error::other(e)))?,
            name: self.name.clone(),
            baud: self.baud,
        })
    }

    /// Read what is there (at least one byte), or `Ok(0)` when the timeout
    /// passed without any.
    pub fn read_some(&mut self, buf: &mut [u8]) -> Result<usize, BoardError> {
        match self.port.read(buf) {
            Ok(0) => Err(BoardError::Closed {
                port: self.name.clone(),
            }),
            Ok(n) => Ok(n),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
                ) =>
            {
                Ok(0)
            }
            Err(e) => Err(self.io(e)),
        }
    }

    /// Write all of `bytes` and flush.
    pub fn send(&mut self, bytes: &[u8]) -> Result<(), BoardError> {
        let r = self.port.write_all(bytes).and_then(|()| self.port.flush());
        r.map_err(|e| self.io(e))
    }

    fn io(&self, error: io::Error) -> BoardError {
        BoardError::Io {
            port: self.name.clone(),
            error,
        }
    }
}

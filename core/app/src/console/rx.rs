//! The console's receive path: the line editor and the queue of finished
//! lines between the byte interrupt and the console task.

use super::MAX_LINE;

/// What a received byte did to the line.
#[derive(Debug, PartialEq, Eq)]
pub enum Edit<'a> {
    /// Nothing to show.
    None,
    /// Echo this printable character.
    Echo(u8),
    /// The last character was erased (echo `"\x08 \x08"`).
    Erase,
    /// A complete, non-empty line of printable ASCII.
    Line(&'a str),
    /// A complete line that cannot be a command.
    Bad(LineError),
}

/// Why a line was refused before parsing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineError {
    /// Longer than [`MAX_LINE`].
    TooLong,
    /// A control character or a non-ASCII byte.
    InvalidCharacter,
    /// Bytes of the line were lost on the way in (the receiver reported an
    /// overrun, framing or noise error).
    Overrun,
    /// The line arrived whole but the receive queue was full.
    Discarded,
}

impl LineError {
    /// A short human-readable reason.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::TooLong => "line too long",
            Self::InvalidCharacter => "invalid character in line",
            Self::Overrun => "input overrun, line discarded",
            Self::Discarded => "input queue full, line discarded",
        }
    }

    /// The code of this error in the receive queue (below 0x20: never a
    /// character of a stored line).
    const fn code(self) -> u8 {
        match self {
            Self::TooLong => 1,
            Self::InvalidCharacter => 2,
            Self::Overrun => 3,
            Self::Discarded => 4,
        }
    }

    /// The error of a queue code.
    const fn from_code(c: u8) -> Self {
        match c {
            1 => Self::TooLong,
            2 => Self::InvalidCharacter,
            4 => Self::Discarded,
            _ => Self::Overrun,
        }
    }
}

/// Collects typed bytes into lines: CR, LF or CR LF end a line, backspace and
/// DEL erase, empty lines are ignored (unless bytes were lost in them: then
/// the line end is answered with [`LineError::Overrun`], so that a lost line
/// is never met with silence).
#[derive(Clone, Debug)]
pub struct LineEditor {
    buf: heapless::Vec<u8, MAX_LINE>,
    error: Option<LineError>,
    /// `buf` holds a line already returned.
    ended: bool,
}

impl Default for LineEditor {
    fn default() -> Self {
        Self::new()
    }
}

impl LineEditor {
    /// An empty line.
    pub const fn new() -> Self {
        Self {
            buf: heapless::Vec::new(),
            error: None,
            ended: false,
        }
    }

    /// Bytes were lost: the current line is refused at its end.
    pub fn overrun(&mut self) {
        self.error = Some(LineError::Overrun);
    }

    /// Feed one received byte.
    pub fn push(&mut self, c: u8) -> Edit<'_> {
        if core::mem::take(&mut self.ended) {
            self.buf.clear();
        }
        match c {
            b'\r' | b'\n' => {
                if let Some(e) = self.error.take() {
                    self.buf.clear();
                    return Edit::Bad(e);
                }
                if self.buf.is_empty() {
                    return Edit::None;
                }
                // The line stays in the buffer while the caller reads it; the
                // next byte starts a new one.
                self.ended = true;
                // Only printable ASCII is ever stored: always valid UTF-8.
                match core::str::from_utf8(&self.buf) {
                    Ok(s) => Edit::Line(s),
                    Err(_) => Edit::Bad(LineError::InvalidCharacter),
                }
            }
            0x08 | 0x7f => {
                if self.error.is_none() && self.buf.pop().is_some() {
                    Edit::Erase
                } else {
                    Edit::None
                }
            }
            0x20..=0x7e => {
                if self.error.is_some() {
                    return Edit::None;
                }
                if self.buf.push(c).is_err() {
                    // The line is full (MAX_LINE characters).
                    self.error = Some(LineError::TooLong);
                    return Edit::None;
                }
                Edit::Echo(c)
            }
            _ => {
                if self.error.is_none() {
                    self.error = Some(LineError::InvalidCharacter);
                }
                Edit::None
            }
        }
    }
}

/// Capacity of the console's receive queue, bytes.
///
/// The console task answers one line at a time and may be busy for a while
/// (the longest reply, `get` of every setting, is about 1.7 kB: 0.15 s at
/// 115 200 baud, while the same 0.15 s can bring 1.7 kB of input). The queue
/// holds complete lines only, each as its characters and one end byte, so
/// 2 048 bytes hold any twenty lines of the longest length ([`MAX_LINE`] + 1
/// bytes each) or a 500-byte paste of short lines three times over. Beyond it,
/// lines are still answered, with [`LineError::Discarded`].
pub const RX_QUEUE_BYTES: usize = 2048;

/// Capacity of the echo queue, bytes (echo is best effort: a full queue drops
/// echoed characters, never lines).
pub const ECHO_BYTES: usize = 64;

/// What the console task takes from the [`Receiver`].
#[derive(Debug, PartialEq, Eq)]
pub enum Received<'a> {
    /// A complete, non-empty line of printable ASCII.
    Line(&'a str),
    /// A line that is refused before parsing (one error reply).
    Bad(LineError),
}

/// The console's receive path, from the byte interrupt to the console task.
///
/// The interrupt feeds every byte to [`Receiver::receive`], which runs the
/// line editor at once and queues each finished line (or the reason it was
/// refused) in a byte ring of `N` bytes: a line end is never lost, however
/// long the console task is busy. When a line does not fit, it is counted, and
/// so is every line after it until the queue has been emptied; the console
/// task then gets one [`LineError::Discarded`] per counted line, after the
/// queued ones. So every line gets exactly one reply, in order, whatever the
/// input rate.
///
/// The interrupt and the console task share the receiver through a lock
/// (RTIC resource); each call is short (at most one line copied).
#[derive(Clone, Debug)]
pub struct Receiver<const N: usize> {
    editor: LineEditor,
    /// Finished lines: their characters, then an end byte (0 for a good line,
    /// a [`LineError`] code otherwise; both below 0x20, never a character).
    lines: heapless::Deque<u8, N>,
    /// Lines that did not fit, answered after the queue has drained.
    discarded: u32,
    /// Lines discarded since start-up (statistics).
    discarded_total: u32,
    echo_on: bool,
    echo: heapless::Deque<u8, ECHO_BYTES>,
}

impl<const N: usize> Default for Receiver<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Receiver<N> {
    /// Empty, echo off.
    pub const fn new() -> Self {
        Self {
            editor: LineEditor::new(),
            lines: heapless::Deque::new(),
            discarded: 0,
            discarded_total: 0,
            echo_on: false,
            echo: heapless::Deque::new(),
        }
    }

    /// One received byte (called from the receive interrupt).
    pub fn receive(&mut self, byte: u8) {
        match self.editor.push(byte) {
            Edit::None => {}
            Edit::Echo(c) => self.echo_bytes(&[c]),
            Edit::Erase => self.echo_bytes(b"\x08 \x08"),
            Edit::Line(line) => {
                if self.echo_on {
                    push_all(&mut self.echo, b"\r\n");
                }
                enqueue(
                    &mut self.lines,
                    &mut self.discarded,
                    &mut self.discarded_total,
                    line.as_bytes(),
                    0,
                );
            }
            Edit::Bad(e) => {
                if self.echo_on {
                    push_all(&mut self.echo, b"\r\n");
                }
                enqueue(
                    &mut self.lines,
                    &mut self.discarded,
                    &mut self.discarded_total,
                    &[],
                    e.code(),
                );
            }
        }
    }

    /// The receiver lost bytes (overrun, framing or noise error): the line
    /// being typed is answered with [`LineError::Overrun`].
    pub fn lost(&mut self) {
        self.editor.overrun();
    }

    /// Echo typed characters from now on (or not).
    pub fn set_echo(&mut self, on: bool) {
        self.echo_on = on;
        if !on {
            self.echo.clear();
        }
    }

    /// Whether typed characters are echoed.
    pub fn echo(&self) -> bool {
        self.echo_on
    }

    /// The next byte to echo, if any (take them all before the next line, so
    /// that a line's echo comes before its reply).
    pub fn next_echo(&mut self) -> Option<u8> {
        self.echo.pop_front()
    }

    /// The next line, copied into `buf`: queued lines in order, then one
    /// [`LineError::Discarded`] per line that did not fit.
    pub fn next<'b>(&mut self, buf: &'b mut [u8; MAX_LINE]) -> Option<Received<'b>> {
        if self.lines.is_empty() {
            if self.discarded == 0 {
                return None;
            }
            self.discarded -= 1;
            return Some(Received::Bad(LineError::Discarded));
        }
        let mut n = 0;
        while let Some(b) = self.lines.pop_front() {
            if b < 0x20 {
                if b != 0 {
                    return Some(Received::Bad(LineError::from_code(b)));
                }
                // Stored lines are printable ASCII of at most MAX_LINE bytes.
                return Some(match buf.get(..n).map(core::str::from_utf8) {
                    Some(Ok(s)) => Received::Line(s),
                    _ => Received::Bad(LineError::InvalidCharacter),
                });
            }
            if let Some(slot) = buf.get_mut(n) {
                *slot = b;
                n += 1;
            }
        }
        // A line without its end byte cannot be queued (see `enqueue`).
        Some(Received::Bad(LineError::Overrun))
    }

    /// Bytes waiting in the line queue.
    pub fn queued_bytes(&self) -> usize {
        self.lines.len()
    }

    /// Lines answered with [`LineError::Discarded`] since start-up.
    pub fn discarded_total(&self) -> u32 {
        self.discarded_total
    }

    fn echo_bytes(&mut self, bytes: &[u8]) {
        if self.echo_on {
            push_all(&mut self.echo, bytes);
        }
    }
}

/// Push what fits of `bytes` (echo is best effort).
fn push_all<const M: usize>(q: &mut heapless::Deque<u8, M>, bytes: &[u8]) {
    for &b in bytes {
        if q.push_back(b).is_err() {
            return;
        }
    }
}

/// Queue one line (`chars`, then the end byte `end`) whole, or count it as
/// discarded. Once a line was discarded, later lines are discarded too until
/// the queue has drained, so that the replies keep the order of the lines.
fn enqueue<const N: usize>(
    q: &mut heapless::Deque<u8, N>,
    discarded: &mut u32,
    total: &mut u32,
    chars: &[u8],
    end: u8,
) {
    let fits = q.capacity() - q.len() > chars.len();
    if *discarded > 0 || !fits {
        *discarded = discarded.saturating_add(1);
        *total = total.saturating_add(1);
        return;
    }
    for &b in chars.iter().chain(core::iter::once(&end)) {
        // Cannot fail: the space was checked above.
        let _ = q.push_back(b);
    }
}

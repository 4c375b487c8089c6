//! Hardware-in-the-loop frames: the binary link between a plant simulated on a
//! host and the firmware's control task (shared by both ends).
//!
//! # Wire format
//! One frame = COBS( postcard(message) ++ CRC-16 ) ++ `0x00`.
//!
//! * the message is serialised with postcard (integers as varints, `f32` as its
//!   4 little-endian bytes, so values cross the link bit for bit);
//! * the CRC is CRC-16/IBM-3740 (CCITT-FALSE) of the postcard bytes, appended
//!   little-endian;
//! * COBS removes every `0x00` from the frame, so `0x00` delimits frames and a
//!   receiver that lost bytes resynchronises at the next delimiter.
//!
//! # Lockstep
//! The host sends one [`SampleFrame`] per control tick, with `seq` counting up
//! from 0 after the firmware entered HIL mode (or after a fault was cleared);
//! the firmware runs exactly one control tick on it and answers with one
//! [`CommandFrame`] carrying the same `seq`. [`LinkMonitor`] is the firmware's
//! bookkeeping: a frame that fails to decode (COBS, CRC, postcard or length)
//! is *corrupt*, a gap in `seq` means frames were *lost*, and no frame for
//! longer than the timeout while the loop is running is *late*. Each is counted
//! and is a fault: the command falls to zero, a wrong command is never sent.
//!
//! # Start-up
//! Supervision starts with the first valid frame, not when the firmware
//! enters HIL mode or is armed: a host may take as long as it needs to open
//! its port. Until then the link is *waiting*: bytes that do not form a valid
//! frame with `seq` 0 (a banner, an echo, line noise when a port opens, a
//! stale frame of an earlier run) are counted as *skipped* and get no reply,
//! no timeout runs, and nothing trips. A host starts with a lone `0x00`, which
//! ends whatever partial frame the firmware's reader holds, and then sends
//! `seq` 0; it discards received bytes up to the first valid reply.

use serde::{Deserialize, Serialize};

/// Largest encoded frame, delimiter included, bytes.
pub const MAX_FRAME_LEN: usize = 64;

/// Largest postcard payload before the CRC and COBS, bytes.
const MAX_PAYLOAD: usize = MAX_FRAME_LEN - 4;

/// The CRC of the frames.
const CRC16: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);

/// Host to firmware, once per control tick: the reference and what the
/// (simulated) sensors read at the tick, SI units, exactly the core's
/// [`dca_core::controller::Sample`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SampleFrame {
    /// Tick index, counting from 0.
    pub seq: u32,
    /// Position reference, m.
    pub ref_m: f32,
    /// Actuating piston position (LVDT), m.
    pub xo_m: f32,
    /// Power piston position (encoder), m.
    pub xi_m: f32,
    /// Line-1 pressure, gauge, Pa.
    pub p1_pa: f32,
    /// Line-2 pressure, gauge, Pa.
    pub p2_pa: f32,
    /// Load force, N.
    pub ft_n: f32,
}

impl SampleFrame {
    /// The controller sample carried by this frame.
    pub fn sample(&self) -> dca_core::controller::Sample {
        dca_core::controller::Sample {
            xo_m: self.xo_m,
            xi_m: self.xi_m,
            p1_pa: self.p1_pa,
            p2_pa: self.p2_pa,
            ft_n: self.ft_n,
        }
    }
}

/// Firmware to host, once per received sample frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CommandFrame {
    /// The `seq` of the sample frame this answers (the expected one when that
    /// frame was corrupt).
    pub seq: u32,
    /// Drive speed command to apply over the next tick, m/s (0 unless the
    /// supervisor is armed or running without a fault).
    pub v_cmd_mps: f32,
    /// Supervisor state ([`crate::supervisor::State`] as `u8`).
    pub state: u8,
    /// Latched fault bits ([`crate::supervisor::Faults`]).
    pub faults: u16,
    /// Controller flags of this tick ([`dca_core::controller::Flags`]).
    pub flags: u8,
}

/// Why a frame could not be built or read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// The output buffer is too small, or the frame exceeds [`MAX_FRAME_LEN`].
    Length,
    /// COBS decoding failed.
    Cobs,
    /// The CRC does not match.
    Crc,
    /// The payload is not a valid message.
    Payload,
}

impl FrameError {
    /// A short human-readable reason.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Length => "frame too long",
            Self::Cobs => "bad COBS stuffing",
            Self::Crc => "CRC mismatch",
            Self::Payload => "malformed payload",
        }
    }
}

/// Encode `msg` as a complete frame (delimiter included) into `out`; returns
/// the number of bytes written.
pub fn encode<T: Serialize>(msg: &T, out: &mut [u8]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_PAYLOAD];
    let n = postcard::to_slice(msg, &mut raw[..MAX_PAYLOAD - 2])
        .map_err(|_| FrameError::Length)?
        .len();
    // n <= MAX_PAYLOAD - 2: the `get`s below always succeed (no panic paths,
    // which would link the formatting machinery into the firmware).
    let crc = CRC16.checksum(raw.get(..n).unwrap_or(&[]));
    if let Some(dst) = raw.get_mut(n..n + 2) {
        dst.copy_from_slice(&crc.to_le_bytes());
    }
    let n = n + 2;
    if out.len() < cobs::max_encoding_length(n) + 1 {
        return Err(FrameError::Length);
    }
    // `try_encode`, not `encode`: the same bytes, and no `unwrap` (whose panic
    // message would link the Debug formatting machinery into the firmware).
    let m = cobs::try_encode(raw.get(..n).unwrap_or(&[]), out).map_err(|_| FrameError::Length)?;
    *out.get_mut(m).ok_or(FrameError::Length)? = 0;
    Ok(m + 1)
}

/// Decode one frame given without its `0x00` delimiter. The buffer is decoded
/// in place (its contents are destroyed). Only what [`encode`] writes is
/// accepted: a payload that decodes but is not the canonical encoding of its
/// message (postcard reads an over-long varint such as `80 00` for 0) is
/// refused as [`FrameError::Payload`], even with a valid CRC.
pub fn decode<'a, T: Deserialize<'a> + Serialize>(frame: &'a mut [u8]) -> Result<T, FrameError> {
    if frame.len() > MAX_FRAME_LEN {
        return Err(FrameError::Length);
    }
    // A body never holds the delimiter: what follows one is another frame.
    if frame.contains(&0) {
        return Err(FrameError::Cobs);
    }
    let n = cobs::decode_in_place(frame).map_err(|_| FrameError::Cobs)?;
    if n < 3 {
        return Err(FrameError::Payload);
    }
    let (payload, crc) = frame.get(..n).ok_or(FrameError::Cobs)?.split_at(n - 2);
    if CRC16.checksum(payload) != u16::from_le_bytes([crc[0], crc[1]]) {
        return Err(FrameError::Crc);
    }
    let (msg, rest) = postcard::take_from_bytes::<T>(payload).map_err(|_| FrameError::Payload)?;
    if !rest.is_empty() {
        return Err(FrameError::Payload);
    }
    let mut canonical = [0u8; MAX_PAYLOAD];
    match postcard::to_slice(&msg, &mut canonical) {
        Ok(c) if *c == *payload => Ok(msg),
        _ => Err(FrameError::Payload),
    }
}

/// Collects bytes from a stream into frames at the `0x00` delimiters.
#[derive(Clone, Debug)]
pub struct FrameReader {
    buf: heapless::Vec<u8, MAX_FRAME_LEN>,
    overflow: bool,
    /// `buf` holds a frame already returned.
    ended: bool,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self::new()
    }
}

/// What one received byte completed.
#[derive(Debug, PartialEq, Eq)]
pub enum ReadEvent<'a> {
    /// A frame body (without the delimiter), to be given to [`decode`].
    Frame(&'a mut [u8]),
    /// More than [`MAX_FRAME_LEN`] bytes without a delimiter: dropped.
    Overflow,
}

impl FrameReader {
    /// An empty reader.
    pub const fn new() -> Self {
        Self {
            buf: heapless::Vec::new(),
            overflow: false,
            ended: false,
        }
    }

    /// Forget a partial frame.
    pub fn reset(&mut self) {
        self.buf.clear();
        self.overflow = false;
        self.ended = false;
    }

    /// Feed one byte. A delimiter after at least one byte completes a frame
    /// (or reports the overflow of an over-long one); empty frames (two
    /// delimiters in a row) are skipped.
    pub fn push(&mut self, byte: u8) -> Option<ReadEvent<'_>> {
        if core::mem::take(&mut self.ended) {
            self.buf.clear();
        }
        if byte == 0 {
            if core::mem::take(&mut self.overflow) {
                self.buf.clear();
                return Some(ReadEvent::Overflow);
            }
            if self.buf.is_empty() {
                return None;
            }
            // The frame stays in the buffer while the caller decodes it (in
            // place); the next byte starts a new one.
            self.ended = true;
            return Some(ReadEvent::Frame(&mut self.buf));
        }
        if self.buf.push(byte).is_err() {
            self.overflow = true;
        }
        None
    }
}

/// Link error counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkCounters {
    /// Frames received and accepted.
    pub good: u32,
    /// Frames that failed to decode (COBS, CRC, payload, over-long).
    pub corrupt: u32,
    /// Frames missing from the `seq` sequence (gaps and repeats).
    pub lost: u32,
    /// Timeouts: no frame within the timeout while running.
    pub late: u32,
    /// Frames (or stray bytes up to a delimiter) before the link was live:
    /// ignored, no fault.
    pub skipped: u32,
}

/// What the monitor concluded about one received frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkError {
    /// The frame failed to decode.
    Corrupt(FrameError),
    /// The frame's `seq` is not the expected one.
    Lost {
        /// The `seq` the monitor expected.
        expected: u32,
        /// The `seq` the frame carried.
        got: u32,
    },
    /// No frame arrived within the timeout.
    Late,
}

impl LinkError {
    /// A short human-readable reason.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Corrupt(e) => e.as_str(),
            Self::Lost { .. } => "frame lost (sequence gap)",
            Self::Late => "frame late (timeout)",
        }
    }
}

/// The firmware's view of the HIL link: start-up, sequence and timeout checks
/// and counters. Pure bookkeeping; time is given in control-timer ticks.
#[derive(Clone, Copy, Debug, Default)]
pub struct LinkMonitor {
    expected: u32,
    idle_ticks: u32,
    /// A valid frame with `seq` 0 has arrived since the last restart.
    live: bool,
    counters: LinkCounters,
}

impl LinkMonitor {
    /// A waiting monitor (expecting `seq` 0 to start).
    pub const fn new() -> Self {
        Self {
            expected: 0,
            idle_ticks: 0,
            live: false,
            counters: LinkCounters {
                good: 0,
                corrupt: 0,
                lost: 0,
                late: 0,
                skipped: 0,
            },
        }
    }

    /// Wait for a new start (`seq` 0) and stop the timeout (counters are
    /// kept).
    pub fn restart(&mut self) {
        self.expected = 0;
        self.idle_ticks = 0;
        self.live = false;
    }

    /// The `seq` expected next.
    pub fn expected(&self) -> u32 {
        self.expected
    }

    /// Whether the link is supervised (a valid first frame has arrived).
    pub fn is_live(&self) -> bool {
        self.live
    }

    /// The counters so far.
    pub fn counters(&self) -> LinkCounters {
        self.counters
    }

    /// Zero the counters.
    pub fn clear_counters(&mut self) {
        self.counters = LinkCounters::default();
    }

    /// Check one received frame body (without its delimiter).
    ///
    /// While waiting, a valid frame with `seq` 0 makes the link live and is
    /// returned; anything else is skipped (`Ok(None)`). Once live, the frame
    /// with the expected `seq` is returned and the next one is expected; a
    /// frame that fails to decode or breaks the sequence is counted and is an
    /// error, and the expected `seq` stays (the host restarts the sequence
    /// after the fault is cleared).
    pub fn receive(&mut self, body: &mut [u8]) -> Result<Option<SampleFrame>, LinkError> {
        let decoded: Result<SampleFrame, FrameError> = decode(body);
        if !self.live {
            return match decoded {
                Ok(f) if f.seq == 0 => {
                    self.live = true;
                    self.idle_ticks = 0;
                    self.expected = 1;
                    self.counters.good = self.counters.good.saturating_add(1);
                    Ok(Some(f))
                }
                _ => {
                    self.counters.skipped = self.counters.skipped.saturating_add(1);
                    Ok(None)
                }
            };
        }
        self.idle_ticks = 0;
        let frame = match decoded {
            Ok(f) => f,
            Err(e) => {
                self.counters.corrupt = self.counters.corrupt.saturating_add(1);
                return Err(LinkError::Corrupt(e));
            }
        };
        if frame.seq != self.expected {
            self.counters.lost = self.counters.lost.saturating_add(1);
            return Err(LinkError::Lost {
                expected: self.expected,
                got: frame.seq,
            });
        }
        self.expected = self.expected.wrapping_add(1);
        self.counters.good = self.counters.good.saturating_add(1);
        Ok(Some(frame))
    }

    /// Count an over-long frame or a receiver error (the reader's
    /// [`ReadEvent::Overflow`], an overrun): an error once live, skipped
    /// while waiting.
    pub fn overflow(&mut self) -> Option<LinkError> {
        if !self.live {
            self.counters.skipped = self.counters.skipped.saturating_add(1);
            return None;
        }
        self.idle_ticks = 0;
        self.counters.corrupt = self.counters.corrupt.saturating_add(1);
        Some(LinkError::Corrupt(FrameError::Length))
    }

    /// One control-timer tick passed while frames are expected. Returns
    /// [`LinkError::Late`] once, when `timeout_ticks` ticks passed without a
    /// frame while live (`timeout_ticks` = 0 never times out; a waiting link
    /// never times out).
    pub fn tick(&mut self, timeout_ticks: u32) -> Option<LinkError> {
        if timeout_ticks == 0 || !self.live {
            return None;
        }
        self.idle_ticks = self.idle_ticks.saturating_add(1);
        if self.idle_ticks == timeout_ticks {
            self.counters.late = self.counters.late.saturating_add(1);
            return Some(LinkError::Late);
        }
        None
    }

    /// Restart the timeout without a frame (e.g. while frames are not expected).
    pub fn idle(&mut self) {
        self.idle_ticks = 0;
    }
}

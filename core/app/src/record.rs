//! The on-board record: every control tick of a run, packed into 16 bytes, in
//! the board's RAM, sent over the console as checked binary frames.
//!
//! `record S` (the console) arms a record of S seconds; it starts at the first
//! tick in state `running` (the next `goto` or `sine`, or a HIL run's first
//! frame) and takes every tick from then on, whatever the state (a fault and
//! the ticks after it are recorded), until S seconds are full or `dump` ends
//! it. [`Recorder::push`] is the control tick's part: a few dozen
//! instructions, no loop, no division.
//!
//! # A row ([`ROW_BYTES`] = 16 bytes, the values as the sensors deliver them)
//!
//! | column | packed as | resolution |
//! |---|---|---|
//! | `xo_m`, `p1_pa`, `p2_pa`, `ft_n` | the 12-bit ADC code (0..4095) of the calibration in force when the record was armed | one code: 29.3 um, 2.44 kPa, 2.44 kPa, 0.98 N with the factory calibration |
//! | `xi_m` | the encoder count, 24 bits signed | one count: 0.2 um with the factory calibration |
//! | `ref_m` | 24 bits signed, units of 2^-23 m, range [-1, 1) m | 2^-23 m = 0.119 um |
//! | `vcmd_mps` | 24 bits signed, units of 2^-23 m/s, range [-1, 1) m/s (v_max <= 1 m/s) | 2^-23 m/s = 0.119 um/s |
//! | `faults` | the 8 fault bits | exact |
//!
//! On the board the sensor columns are the codes the ADC and the encoder
//! delivered (the calibration `offset + gain * code` inverted, exactly, well
//! within a code). A value from elsewhere (a HIL frame, the emulated build's
//! simulated sensors) is recorded as the nearest code, clamped to the
//! channel's range: what a board's converter would have delivered. Read back,
//! a code gives the calibrated value the board computes from it
//! ([`RecordHead::row`], the board's own f32 arithmetic), so a HIL run whose
//! host models the board's sensors (`--sensors realistic`) is recorded
//! exactly as the board read it. A non-finite value is recorded as 0.
//!
//! Layout of the 128-bit row, little-endian, bit 0 first: Xo code (12 bits),
//! P1 (12), P2 (12), Ft (12), Xi (24), ref (24), command (24), faults (8).
//!
//! # The dump
//! `dump` answers with a line `dump rows=N frames=F`, then F frames of
//! [`crate::frame`] (COBS, postcard, CRC-16, `0x00`-delimited), then `ok`: a
//! [`RecordHead`] (the row count, the controller and the calibration) and
//! `F - 1` [`RecordChunk`]s of [`CHUNK_ROWS`] rows, their `seq` counting
//! from one. A reader checks every frame's CRC and sequence: a lost or
//! damaged frame makes the whole dump an error, never a shorter log.

use dca_core::controller::Sample;
use serde::{Deserialize, Serialize};

use crate::settings::{Calibration, ChannelCal};

/// Bytes of one recorded tick.
pub const ROW_BYTES: usize = 16;

/// One recorded tick, packed (see the module documentation).
pub type PackedRow = [u8; ROW_BYTES];

/// Rows per [`RecordChunk`] (a frame stays within [`crate::frame::MAX_FRAME_LEN`]).
pub const CHUNK_ROWS: usize = 3;

/// The record's time step, s: one row per control tick.
pub const RECORD_DT_S: f64 = 1.0e-3;

/// Resolution of the `ref_m` column, m (2^-23).
pub const REF_LSB_M: f64 = 1.0 / (1u32 << 23) as f64;

/// Resolution of the `vcmd_mps` column, m/s (2^-23).
pub const VCMD_LSB_MPS: f64 = 1.0 / (1u32 << 23) as f64;

/// Largest ADC code (12 bits).
pub const ADC_MAX: u32 = 4095;

const I24_MAX: i32 = (1 << 23) - 1;
const I24_MIN: i32 = -(1 << 23);
const SCALE_Q23: f32 = (1u32 << 23) as f32;

/// The nearest whole number of `x` (half away from zero), clamped to
/// `[lo, hi]`; 0 when `x` is not a number. On the board a few instructions:
/// the cast is the FPU's saturating conversion (NaN gives 0, +-inf the ends
/// of i32), no call.
#[inline(always)]
fn quantise(x: f32, lo: i32, hi: i32) -> i32 {
    let n = (x + libm::copysignf(0.5, x)) as i32;
    n.clamp(lo, hi)
}

/// One channel's inverse calibration.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Inverse {
    offset: f32,
    inv_gain: f32,
}

impl Inverse {
    fn of(c: &ChannelCal) -> Self {
        let inv = 1.0 / c.gain;
        Self {
            offset: c.offset,
            inv_gain: if inv.is_finite() { inv } else { 0.0 },
        }
    }

    #[inline(always)]
    fn code(&self, v: f32, lo: i32, hi: i32) -> i32 {
        quantise((v - self.offset) * self.inv_gain, lo, hi)
    }
}

/// Packs a tick into a row with one calibration.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Packer {
    xo: Inverse,
    p1: Inverse,
    p2: Inverse,
    ft: Inverse,
    xi: Inverse,
}

impl Packer {
    /// The packer of calibration `cal`.
    pub fn new(cal: &Calibration) -> Self {
        Self {
            xo: Inverse::of(&cal.lvdt),
            p1: Inverse::of(&cal.p1),
            p2: Inverse::of(&cal.p2),
            ft: Inverse::of(&cal.force),
            xi: Inverse::of(&cal.encoder),
        }
    }

    /// One tick as a row.
    pub fn pack(&self, ref_m: f32, v_cmd_mps: f32, s: &Sample, faults: u16) -> PackedRow {
        let adc = |inv: &Inverse, v: f32| inv.code(v, 0, ADC_MAX as i32) as u32;
        let xo = adc(&self.xo, s.xo_m);
        let p1 = adc(&self.p1, s.p1_pa);
        let p2 = adc(&self.p2, s.p2_pa);
        let ft = adc(&self.ft, s.ft_n);
        let xi = self.xi.code(s.xi_m, I24_MIN, I24_MAX) as u32 & 0xff_ffff;
        let r = quantise(ref_m * SCALE_Q23, I24_MIN, I24_MAX) as u32 & 0xff_ffff;
        let v = quantise(v_cmd_mps * SCALE_Q23, I24_MIN, I24_MAX) as u32 & 0xff_ffff;
        let w0 = xo | p1 << 12 | (p2 & 0xff) << 24;
        let w1 = p2 >> 8 | ft << 4 | (xi & 0xffff) << 16;
        let w2 = xi >> 16 | r << 8;
        let w3 = v | u32::from(faults as u8) << 24;
        let [a0, a1, a2, a3] = w0.to_le_bytes();
        let [b0, b1, b2, b3] = w1.to_le_bytes();
        let [c0, c1, c2, c3] = w2.to_le_bytes();
        let [d0, d1, d2, d3] = w3.to_le_bytes();
        [
            a0, a1, a2, a3, b0, b1, b2, b3, c0, c1, c2, c3, d0, d1, d2, d3,
        ]
    }
}

/// A row's fields as integers (codes, counts, units of the resolution).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Fields {
    /// ADC codes: Xo, P1, P2, Ft.
    pub adc: [u16; 4],
    /// Encoder count.
    pub xi_count: i32,
    /// Reference, units of [`REF_LSB_M`].
    pub ref_q23: i32,
    /// Command, units of [`VCMD_LSB_MPS`].
    pub vcmd_q23: i32,
    /// Fault bits.
    pub faults: u8,
}

fn sign24(x: u32) -> i32 {
    ((x << 8) as i32) >> 8
}

/// The fields of a packed row.
pub fn fields(row: &PackedRow) -> Fields {
    let mut w = [0u32; 4];
    for (dst, src) in w.iter_mut().zip(row.chunks_exact(4)) {
        let mut b = [0u8; 4];
        b.copy_from_slice(src);
        *dst = u32::from_le_bytes(b);
    }
    let code = |x: u32| (x & 0xfff) as u16;
    Fields {
        adc: [
            code(w[0]),
            code(w[0] >> 12),
            code(w[0] >> 24 | w[1] << 8),
            code(w[1] >> 4),
        ],
        xi_count: sign24(w[1] >> 16 | (w[2] & 0xff) << 16),
        ref_q23: sign24(w[2] >> 8),
        vcmd_q23: sign24(w[3] & 0xff_ffff),
        faults: (w[3] >> 24) as u8,
    }
}

/// A recorded tick read back.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RecordedRow {
    /// Reference, m.
    pub ref_m: f64,
    /// Drive command, m/s.
    pub v_cmd_mps: f64,
    /// The sensor readings, calibrated as the board calibrates them.
    pub sample: Sample,
    /// Latched fault bits.
    pub faults: u16,
}

/// The first frame of a dump: what the rows need to be read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RecordHead {
    /// Rows in the dump.
    pub rows: u32,
    /// The controller when the record was armed
    /// ([`dca_core::controller::ControllerKind::ALL`] index).
    pub controller: u8,
    /// The calibration the rows were packed with: gain and offset of the
    /// LVDT, P1, P2, force and encoder channels.
    pub cal: [f32; 10],
}

impl RecordHead {
    /// The head of `rows` rows packed with `cal`.
    pub fn new(rows: u32, controller: u8, cal: &Calibration) -> Self {
        let ch = [cal.lvdt, cal.p1, cal.p2, cal.force, cal.encoder];
        let mut c = [0.0f32; 10];
        for (pair, ch) in c.chunks_exact_mut(2).zip(ch) {
            pair[0] = ch.gain;
            pair[1] = ch.offset;
        }
        Self {
            rows,
            controller,
            cal: c,
        }
    }

    fn channel(&self, i: usize) -> ChannelCal {
        ChannelCal {
            gain: self.cal[2 * i],
            offset: self.cal[2 * i + 1],
        }
    }

    /// A row read back: the sensor codes through the calibration (in f32,
    /// as the board computes them), the reference and command scaled.
    pub fn row(&self, row: &PackedRow) -> RecordedRow {
        let f = fields(row);
        let adc = |i: usize| self.channel(i).apply(f32::from(f.adc[i]));
        RecordedRow {
            ref_m: f64::from(f.ref_q23) * REF_LSB_M,
            v_cmd_mps: f64::from(f.vcmd_q23) * VCMD_LSB_MPS,
            sample: Sample {
                xo_m: adc(0),
                p1_pa: adc(1),
                p2_pa: adc(2),
                ft_n: adc(3),
                xi_m: self.channel(4).apply(f.xi_count as f32),
            },
            faults: u16::from(f.faults),
        }
    }

    /// Frames of a dump of this head's rows, the head's included.
    pub fn frames(&self) -> u32 {
        1 + self.rows.div_ceil(CHUNK_ROWS as u32)
    }
}

/// A dump frame after the head: up to [`CHUNK_ROWS`] rows (the last chunk's
/// unused rows are zero; the head's row count says which are rows).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RecordChunk {
    /// Frame number in the dump, 1 for the first chunk.
    pub seq: u32,
    /// The rows.
    pub rows: [PackedRow; CHUNK_ROWS],
}

/// Where a record stands.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RecordState {
    /// Nothing armed; rows of an earlier record may be kept.
    #[default]
    Off,
    /// Waiting for the first tick in state `running`.
    Armed,
    /// Taking every tick.
    Recording,
    /// Full, or ended by `dump`.
    Done,
}

impl RecordState {
    /// `off`, `armed`, `recording` or `done`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Off => "off",
            Self::Armed => "armed",
            Self::Recording => "recording",
            Self::Done => "done",
        }
    }
}

/// What the console shows of a record.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RecordInfo {
    /// Where it stands.
    pub state: RecordState,
    /// Rows taken.
    pub rows: u32,
    /// Rows asked for.
    pub wanted: u32,
    /// Rows the board's buffer holds.
    pub capacity: u32,
    /// The head of a dump of the rows taken.
    pub head: RecordHead,
}

/// Why a record cannot be armed or dumped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordError {
    /// More rows than the buffer holds, or none.
    Length,
    /// Nothing recorded.
    Empty,
}

impl RecordError {
    /// The console's reason.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Length => "record length must be within the board's buffer (see 'record')",
            Self::Empty => "nothing recorded",
        }
    }
}

/// The record in two blocks of RAM (the board: main SRAM and the CCM RAM),
/// rows `0 .. a.len()` in `a`, the rest in `b`.
#[derive(Debug)]
pub struct Recorder<'a> {
    a: &'a mut [PackedRow],
    b: &'a mut [PackedRow],
    state: RecordState,
    len: u32,
    wanted: u32,
    packer: Packer,
    head: RecordHead,
}

impl<'a> Recorder<'a> {
    /// A recorder over the blocks `a` and `b`, off.
    pub fn new(a: &'a mut [PackedRow], b: &'a mut [PackedRow]) -> Self {
        Self {
            a,
            b,
            state: RecordState::Off,
            len: 0,
            wanted: 0,
            packer: Packer::default(),
            head: RecordHead::default(),
        }
    }

    /// Rows the blocks hold.
    pub fn capacity(&self) -> u32 {
        (self.a.len() + self.b.len()) as u32
    }

    /// Arm a record of `rows` ticks packed with `cal` (the earlier record is
    /// dropped); `controller` is the law's index for the dump's head.
    pub fn arm(&mut self, rows: u32, cal: &Calibration, controller: u8) -> Result<(), RecordError> {
        if rows == 0 || rows > self.capacity() {
            return Err(RecordError::Length);
        }
        self.state = RecordState::Armed;
        self.len = 0;
        self.wanted = rows;
        self.packer = Packer::new(cal);
        self.head = RecordHead::new(0, controller, cal);
        Ok(())
    }

    /// Drop the record (armed or taken).
    pub fn off(&mut self) {
        self.state = RecordState::Off;
        self.len = 0;
    }

    /// End a record being taken (or armed): what was taken is kept.
    pub fn end(&mut self) {
        if matches!(self.state, RecordState::Armed | RecordState::Recording) {
            self.state = RecordState::Done;
        }
    }

    /// The control tick's part: record this tick if due. `running`: the
    /// supervisor is in state `running` (it starts an armed record).
    #[inline]
    pub fn push(&mut self, running: bool, ref_m: f32, v_cmd_mps: f32, s: &Sample, faults: u16) {
        match self.state {
            RecordState::Armed if running => self.state = RecordState::Recording,
            RecordState::Recording => {}
            _ => return,
        }
        let row = self.packer.pack(ref_m, v_cmd_mps, s, faults);
        let i = self.len as usize;
        let slot = match i.checked_sub(self.a.len()) {
            None => self.a.get_mut(i),
            Some(j) => self.b.get_mut(j),
        };
        if let Some(slot) = slot {
            *slot = row;
            self.len += 1;
        }
        if self.len >= self.wanted {
            self.state = RecordState::Done;
        }
    }

    /// Where the record stands.
    pub fn info(&self) -> RecordInfo {
        RecordInfo {
            state: self.state,
            rows: self.len,
            wanted: self.wanted,
            capacity: self.capacity(),
            head: RecordHead {
                rows: self.len,
                ..self.head
            },
        }
    }

    /// Copy rows `first ..` into `out`; the number copied.
    pub fn rows(&self, first: u32, out: &mut [PackedRow]) -> usize {
        let mut n = 0;
        for (k, dst) in out.iter_mut().enumerate() {
            let i = first as usize + k;
            if i >= self.len as usize {
                break;
            }
            let src = match i.checked_sub(self.a.len()) {
                None => self.a.get(i),
                Some(j) => self.b.get(j),
            };
            if let Some(src) = src {
                *dst = *src;
                n += 1;
            }
        }
        n
    }
}

//! The serial console: bytes typed at the board, one by one, through
//! [`LineEditor`] into [`Console`], against a model of the board built on the
//! core's own [`ControlLoop`] with a flash store that can fail or corrupt.
//!
//! Input: 4 bytes of fault plan (see `Plan`), then the typed bytes.
//!
//! Invariants:
//! * the editor behaves like a reference model of itself (echo, erase, line
//!   length, refused lines);
//! * every line end that completes a non-empty or a refused line gets one
//!   reply of CR LF-ended printable ASCII lines whose last line, and only
//!   that one, is `ok` or `error: <reason>`; an error reply is that one line;
//! * an error changes nothing (settings, machine, flash);
//! * after every command every parameter of [`PARAMS`] lies within its
//!   declared range, the settings validate, and the machine runs the
//!   console's settings;
//! * every image the console stores loads back to the same settings, and a
//!   `load` from an intact flash gives back what was stored.

use dca_app::console::{Console, Edit, LineEditor, LineError, Output, Status, Target, MAX_LINE};
use dca_app::record::{PackedRow, RecordError, RecordInfo, RecordState};
use dca_app::settings::{Calibration, Settings, IMAGE_LEN, PARAMS};
use dca_app::supervisor::{ControlLoop, Refused};
use dca_core::controller::{Controller, Sample};

use super::{crc32_iso_hdlc, Bytes};

/// What the flash does on `store` and `load`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FlashFault {
    /// Works.
    None,
    /// `load` reads the image with one byte flipped (the checksum catches it).
    Flip,
    /// `load` reads the image with one byte flipped and a matching checksum:
    /// the range and design checks behind the checksum must catch it.
    FlipSealed,
    /// `store` fails.
    WriteFails,
}

/// How the machine and the flash misbehave during one run, from the first
/// four input bytes: `[mode, pos lo, pos hi, mask]`.
///
/// `mode` bits 0-1: [`FlashFault`]; bit 2: the flash holds the default image
/// from the start; bit 3: the receiver overruns before every byte whose index
/// is `mask` modulo 64; bits 4-5: after each command the loop ticks with no
/// sample (0), a plausible one (1), a faulty one (2) or alternately (3).
#[derive(Clone, Copy, Debug)]
struct Plan {
    flash: FlashFault,
    preload: bool,
    overrun: Option<usize>,
    tick: u8,
    pos: usize,
    mask: u8,
}

impl Plan {
    fn read(b: &mut Bytes<'_>) -> Self {
        let mode = b.u8();
        let pos = b.u16() as usize % IMAGE_LEN;
        let mask = b.u8();
        Self {
            flash: match mode & 3 {
                0 => FlashFault::None,
                1 => FlashFault::Flip,
                2 => FlashFault::FlipSealed,
                _ => FlashFault::WriteFails,
            },
            preload: mode & 4 != 0,
            overrun: (mode & 8 != 0).then_some(usize::from(mask % 64)),
            tick: (mode >> 4) & 3,
            pos,
            mask: if mask == 0 { 1 } else { mask },
        }
    }
}

/// The board as the console sees it.
struct Model {
    lp: ControlLoop,
    settings: Settings,
    flash: Option<Vec<u8>>,
    /// The image of the last successful `store` of the current command.
    stored: Option<Vec<u8>>,
    telemetry: Option<u32>,
    hil: bool,
    echo: bool,
    applied: u32,
    plan: Plan,
    ticks: u64,
    record: RecordState,
}

/// Everything a refused command must leave as it was.
#[derive(Debug, PartialEq)]
struct Snapshot {
    settings: Settings,
    applied: u32,
    telemetry: Option<u32>,
    hil: bool,
    echo: bool,
    state: u8,
    faults: u16,
    ref_bits: u32,
    flash: Option<Vec<u8>>,
}

impl Model {
    fn new(plan: Plan) -> Self {
        let s = Settings::default();
        let c = s.validate().expect("the defaults validate");
        let mut lp = ControlLoop::new(c, s.limits, 1e-3);
        lp.tick(&Sample::default(), None);
        Self {
            lp,
            settings: s,
            flash: plan.preload.then(|| s.to_image().to_vec()),
            stored: None,
            telemetry: None,
            hil: false,
            echo: false,
            applied: 0,
            plan,
            ticks: 0,
            record: RecordState::Off,
        }
    }

    fn snapshot(&self, console: &Console) -> Snapshot {
        Snapshot {
            settings: *console.settings(),
            applied: self.applied,
            telemetry: self.telemetry,
            hil: self.hil,
            echo: self.echo,
            state: self.lp.supervisor().state() as u8,
            faults: self.lp.supervisor().faults().0,
            ref_bits: self.lp.reference_now().to_bits(),
            flash: self.flash.clone(),
        }
    }

    /// Time passes between two commands.
    fn tick(&mut self) {
        self.ticks += 1;
        let faulty = match self.plan.tick {
            0 => return,
            1 => false,
            2 => true,
            _ => self.ticks.is_multiple_of(2),
        };
        let sample = if faulty {
            Sample {
                xo_m: f32::NAN,
                ..Sample::default()
            }
        } else {
            Sample {
                xo_m: 0.01,
                xi_m: 0.01,
                p1_pa: 1.0e6,
                p2_pa: 1.0e6,
                ft_n: 100.0,
            }
        };
        self.lp.tick(&sample, None);
    }
}

impl Target for Model {
    fn status(&mut self) -> Status {
        Status {
            state: self.lp.supervisor().state() as u8,
            faults: self.lp.supervisor().faults().0,
            sample: *self.lp.last_sample(),
            ref_m: self.lp.reference_now(),
            ticks: self.lp.ticks(),
            hil: self.hil,
            telemetry: self.telemetry.unwrap_or(0),
            ..Status::default()
        }
    }
    fn apply(&mut self, s: &Settings, c: &Controller) -> Result<(), Refused> {
        self.lp.reconfigure(*c, s.limits)?;
        self.settings = *s;
        self.applied += 1;
        Ok(())
    }
    fn arm(&mut self) -> Result<(), Refused> {
        self.lp.arm()
    }
    fn disarm(&mut self) {
        self.lp.disarm()
    }
    fn goto(&mut self, x_m: f32) -> Result<(), Refused> {
        self.lp.goto(x_m)
    }
    fn sine(&mut self, a: f32, f: f32) -> Result<(), Refused> {
        self.lp.sine(a, f)
    }
    fn stop(&mut self) -> Result<(), Refused> {
        self.lp.stop()
    }
    fn clear(&mut self) -> Result<(), Refused> {
        self.lp.supervisor_mut().clear()
    }
    fn store(&mut self, image: &[u8]) -> Result<(), &'static str> {
        if self.plan.flash == FlashFault::WriteFails {
            return Err("flash write failed");
        }
        self.flash = Some(image.to_vec());
        self.stored = Some(image.to_vec());
        Ok(())
    }
    fn load(&mut self, buf: &mut [u8]) -> bool {
        let Some(f) = &self.flash else {
            return false;
        };
        if f.len() != buf.len() {
            return false;
        }
        buf.copy_from_slice(f);
        let n = buf.len();
        match self.plan.flash {
            FlashFault::Flip => buf[self.plan.pos] ^= self.plan.mask,
            FlashFault::FlipSealed if n >= 4 => {
                buf[self.plan.pos] ^= self.plan.mask;
                let crc = crc32_iso_hdlc(&buf[..n - 4]);
                buf[n - 4..].copy_from_slice(&crc.to_le_bytes());
            }
            _ => {}
        }
        true
    }
    fn telemetry(&mut self, d: Option<u32>) {
        self.telemetry = d;
    }
    fn hil(&mut self, on: bool) -> Result<(), Refused> {
        self.lp.supervisor().require_idle()?;
        self.hil = on;
        Ok(())
    }
    fn echo(&mut self, on: bool) {
        self.echo = on;
    }
    // The model's record buffer holds 100 rows and never takes one (its
    // ticks are not control ticks): `record` arms and reports, `dump`
    // answers that nothing was recorded (the dump's frames are tested in
    // dca-app's console tests).
    fn record_arm(&mut self, rows: u32, _: &Calibration, _: u8) -> Result<(), RecordError> {
        if rows == 0 || rows > 100 {
            return Err(RecordError::Length);
        }
        self.record = RecordState::Armed;
        Ok(())
    }
    fn record_off(&mut self) {
        self.record = RecordState::Off;
    }
    fn record_end(&mut self) {
        if self.record == RecordState::Armed {
            self.record = RecordState::Done;
        }
    }
    fn record_info(&mut self) -> RecordInfo {
        RecordInfo {
            state: self.record,
            capacity: 100,
            ..RecordInfo::default()
        }
    }
    fn record_rows(&mut self, _: u32, _: &mut [PackedRow]) -> usize {
        0
    }
}

/// A reply; the model never dumps a record, so it is text only.
#[derive(Default)]
struct Reply(String);

impl std::fmt::Write for Reply {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.0.push_str(s);
        Ok(())
    }
}

impl Output for Reply {
    fn write_bytes(&mut self, bytes: &[u8]) {
        panic!(
            "the model has no record, yet {} bytes of a dump were sent",
            bytes.len()
        );
    }
}

/// What the editor should answer to a byte (the reference model's view).
#[derive(Debug, PartialEq)]
enum Want {
    None,
    Echo(u8),
    Erase,
    Line(Vec<u8>),
    Bad(LineError),
}

/// A reference model of [`LineEditor`], written from its documentation.
#[derive(Default)]
struct Shadow {
    line: Vec<u8>,
    error: Option<LineError>,
}

impl Shadow {
    fn overrun(&mut self) {
        self.error = Some(LineError::Overrun);
    }

    fn push(&mut self, c: u8) -> Want {
        match c {
            b'\r' | b'\n' => {
                let line = std::mem::take(&mut self.line);
                match self.error.take() {
                    Some(e) => Want::Bad(e),
                    None if line.is_empty() => Want::None,
                    None => Want::Line(line),
                }
            }
            0x08 | 0x7f if self.error.is_none() && !self.line.is_empty() => {
                self.line.pop();
                Want::Erase
            }
            0x08 | 0x7f => Want::None,
            0x20..=0x7e if self.error.is_some() => Want::None,
            0x20..=0x7e if self.line.len() == MAX_LINE => {
                self.error = Some(LineError::TooLong);
                Want::None
            }
            0x20..=0x7e => {
                self.line.push(c);
                Want::Echo(c)
            }
            _ => {
                self.error.get_or_insert(LineError::InvalidCharacter);
                Want::None
            }
        }
    }
}

/// Check the shape of one reply; true for `ok`.
fn check_reply(line: &str, reply: &str) -> bool {
    assert!(
        reply
            .bytes()
            .all(|b| matches!(b, 0x20..=0x7e | b'\r' | b'\n')),
        "{line:?}: reply is not printable ASCII: {reply:?}"
    );
    let body = reply
        .strip_suffix("\r\n")
        .unwrap_or_else(|| panic!("{line:?}: reply does not end with CR LF: {reply:?}"));
    let lines: Vec<&str> = body.split("\r\n").collect();
    for l in &lines {
        assert!(
            !l.contains(['\r', '\n']),
            "{line:?}: bare CR or LF in the reply {reply:?}"
        );
    }
    let is_final = |l: &str| l == "ok" || l.starts_with("error: ");
    let (last, before) = lines.split_last().expect("split gives one piece");
    assert!(
        is_final(last),
        "{line:?}: the reply does not end with ok or error: {reply:?}"
    );
    assert!(
        last.len() > "error: ".len() || *last == "ok",
        "{line:?}: an error without a reason: {reply:?}"
    );
    for l in before {
        assert!(
            !is_final(l),
            "{line:?}: a line before the last one looks final: {reply:?}"
        );
    }
    let ok = *last == "ok";
    assert!(
        ok || before.is_empty(),
        "{line:?}: an error reply has more than one line: {reply:?}"
    );
    ok
}

/// Every parameter in its range, the whole valid, the machine in step.
fn check_settings(console: &Console, model: &Model, line: &str) {
    let s = console.settings();
    for p in &PARAMS {
        let v = p.get(s);
        let (lo, hi) = (p.min, p.max);
        assert!(
            v >= lo && v <= hi,
            "{line:?}: {} = {v:e} is outside [{lo:e}, {hi:e}]",
            p.name
        );
    }
    if let Err(e) = s.validate() {
        panic!("{line:?}: the settings in force do not validate: {e:?}");
    }
    assert_eq!(
        *s, model.settings,
        "{line:?}: the machine runs other settings than the console holds"
    );
}

/// Run the typed bytes through the editor and the console; see the module
/// documentation for the input format and the invariants.
pub fn console(data: &[u8]) {
    let mut b = Bytes::new(data);
    let plan = Plan::read(&mut b);
    let typed = b.rest();
    let mut model = Model::new(plan);
    let mut console = Console::new(model.settings);
    let mut editor = LineEditor::new();
    let mut shadow = Shadow::default();
    // What a `load` from an intact flash must give back.
    let mut in_flash: Option<Settings> = plan.preload.then(Settings::default);
    let mut out = Reply::default();
    for (i, &c) in typed.iter().enumerate() {
        if plan.overrun == Some(i % 64) {
            editor.overrun();
            shadow.overrun();
        }
        let want = shadow.push(c);
        let edit = editor.push(c);
        out.0.clear();
        match edit {
            Edit::None => assert_eq!(want, Want::None, "byte {i} ({c:#04x})"),
            Edit::Echo(e) => assert_eq!(want, Want::Echo(e), "byte {i} ({c:#04x})"),
            Edit::Erase => assert_eq!(want, Want::Erase, "byte {i} ({c:#04x})"),
            Edit::Bad(e) => {
                assert_eq!(want, Want::Bad(e), "byte {i} ({c:#04x})");
                console.reject(e, &mut out);
                let reply = &out.0;
                assert!(!check_reply("<refused line>", reply));
                assert_eq!(*reply, format!("error: {}\r\n", e.as_str()));
            }
            Edit::Line(l) => {
                assert_eq!(
                    want,
                    Want::Line(l.as_bytes().to_vec()),
                    "byte {i} ({c:#04x})"
                );
                let line = l.to_string();
                let before = model.snapshot(&console);
                model.stored = None;
                console.execute(&line, &mut model, &mut out);
                let reply = &out.0;
                let ok = check_reply(&line, reply);
                if !ok {
                    assert_eq!(
                        model.snapshot(&console),
                        before,
                        "{line:?} was refused ({reply:?}) but changed something"
                    );
                }
                check_settings(&console, &model, &line);
                if let Some(img) = model.stored.take() {
                    assert!(ok, "{line:?}: stored, then answered {reply:?}");
                    match Settings::from_image(&img) {
                        Ok((s, _)) => assert_eq!(
                            s,
                            *console.settings(),
                            "{line:?}: the stored image loads back to other settings"
                        ),
                        Err(e) => panic!("{line:?}: the stored image does not load back: {e:?}"),
                    }
                    in_flash = Some(*console.settings());
                }
                let cmd = line.split_ascii_whitespace().next();
                if ok && cmd == Some("load") && plan.flash == FlashFault::None {
                    assert_eq!(
                        Some(*console.settings()),
                        in_flash,
                        "load from an intact flash did not give back what was stored"
                    );
                }
                model.tick();
            }
        }
    }
}

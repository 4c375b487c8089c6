//! Settings of the board: controller parameters, sensor calibrations, drive
//! scaling and supervisor limits in one struct, each reachable by a path name
//! (`eso.beta1`, `cal.lvdt.gain`, ...) with a range check, and a binary image
//! with a version and a checksum for the flash store.
//!
//! # Paths
//! [`PARAMS`] is the one table of settable values: name (the unit is the
//! name's suffix, as in the rest of the core), range and type. [`Settings::get`]
//! and [`Settings::with`] go through it, so the console, the store and the
//! tests see the same set. A change is only accepted when the whole result is
//! valid: [`Settings::validate`] designs every controller kind from it (the MPC
//! design runs on the board) and checks the limit pairs.
//!
//! # Stored image
//! ```text
//! magic "DCAS" | format version u16 | value count u16 | layout CRC-32 of the
//! path names | controller kind u8 | 3 bytes 0 | values f64 LE, table order |
//! CRC-32 of everything before it
//! ```
//! All little-endian; the length is a multiple of 4 (flash words). A changed
//! table changes the layout CRC, so an image from another firmware version is
//! refused rather than misread; [`Settings::from_image`] also range-checks every
//! value and validates the result, so a refused image leaves the defaults.

use crate::supervisor::SupervisorLimits;
use dca_core::cmpc::CmpcGains;
use dca_core::controller::{ConfigError, Controller, ControllerConfig, ControllerKind, Preset};
use dca_core::eso::EsoFixedGains;
use dca_core::mpc::MpcGains;

/// Base tick of the firmware, s (the control timer's period).
pub const BOARD_DT_S: f64 = 1.0e-3;

/// Linear calibration of one channel: `value = offset + gain * raw`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelCal {
    /// SI units per raw count.
    pub gain: f32,
    /// SI value at raw count 0.
    pub offset: f32,
}

impl ChannelCal {
    /// The calibration of docs/model.md section 5's 12-bit ADC model over `[lo, hi]`:
    /// reading = lo + (code + 0.5)(hi - lo)/4096.
    pub fn adc12(lo: f64, hi: f64) -> Self {
        let gain = (hi - lo) / 4096.0;
        Self {
            gain: gain as f32,
            offset: (lo + 0.5 * gain) as f32,
        }
    }

    /// The calibrated value of a raw count.
    pub fn apply(&self, raw: f32) -> f32 {
        self.offset + self.gain * raw
    }
}

/// Calibrations of all sensor channels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    /// LVDT (Xo), m per ADC code.
    pub lvdt: ChannelCal,
    /// Line-1 pressure, Pa per ADC code.
    pub p1: ChannelCal,
    /// Line-2 pressure, Pa per ADC code.
    pub p2: ChannelCal,
    /// Force sensor, N per ADC code.
    pub force: ChannelCal,
    /// Motor encoder (Xi), m per count (0.2 um: 10 000 counts/rev, 2 mm lead).
    pub encoder: ChannelCal,
}

impl Calibration {
    /// The sensors of docs/model.md section 5.
    pub fn nominal() -> Self {
        Self {
            lvdt: ChannelCal::adc12(-0.010, 0.110),
            p1: ChannelCal::adc12(0.0, 1.0e7),
            p2: ChannelCal::adc12(0.0, 1.0e7),
            force: ChannelCal::adc12(-2000.0, 2000.0),
            encoder: ChannelCal {
                gain: 0.2e-6,
                offset: 0.0,
            },
        }
    }
}

/// Speed command to servo-drive PWM.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveScale {
    /// PWM duty (0 ... 1) per m/s of commanded speed; the duty saturates at 1.
    pub duty_per_mps: f32,
    /// Swap the direction output's polarity.
    pub invert: bool,
}

impl DriveScale {
    /// Full duty at the nominal speed limit 0.1 m/s.
    pub const DEFAULT: Self = Self {
        duty_per_mps: 10.0,
        invert: false,
    };

    /// Duty (0 ... 1) and direction (true = the positive direction output
    /// level) for a speed command. A non-finite command gives duty 0.
    pub fn duty(&self, v_mps: f32) -> (f32, bool) {
        let d = libm::fabsf(v_mps) * self.duty_per_mps;
        let d = if d.is_finite() { d.min(1.0) } else { 0.0 };
        (d, (v_mps >= 0.0) != self.invert)
    }
}

/// Everything the console can get and set, stored in flash as one image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Controller kind, parameters and limits (`base_dt_s` is the board's).
    pub controller: ControllerConfig,
    /// Supervisor limits.
    pub limits: SupervisorLimits,
    /// Sensor calibrations.
    pub cal: Calibration,
    /// Drive scaling.
    pub drive: DriveScale,
    /// HIL: longest wait for a sample frame while running, ms (0: no timeout).
    pub hil_timeout_ms: u32,
}

impl Default for Settings {
    fn default() -> Self {
        Self::preset(Preset::Paper, ControllerKind::MpcEso)
    }
}

/// How a parameter's value is interpreted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamKind {
    /// Stored as f64.
    F64,
    /// Stored as f32 (printed with 7 significant digits).
    F32,
    /// A whole number.
    Int,
    /// 0 or 1.
    Bool,
}

/// One settable value.
pub struct Param {
    /// Path name; its suffix is the unit (`_s`, `_m`, `_pa`, ...).
    pub name: &'static str,
    /// Smallest accepted value.
    pub min: f64,
    /// Largest accepted value.
    pub max: f64,
    /// Type.
    pub kind: ParamKind,
}

impl core::fmt::Debug for Param {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name)
    }
}

impl Param {
    /// The position of this parameter in [`PARAMS`].
    fn index(&self) -> Option<usize> {
        PARAMS.iter().position(|q| core::ptr::eq(q, self))
    }

    /// The table of the path: `eso` of `eso.beta1`, `cal` of `cal.lvdt.gain`.
    pub fn table(&self) -> &'static str {
        self.name.split_once('.').map_or(self.name, |(t, _)| t)
    }

    /// The path within its table: `beta1` of `eso.beta1`.
    pub fn key(&self) -> &'static str {
        self.name.split_once('.').map_or("", |(_, k)| k)
    }

    /// Whether the value is a controller parameter (a field of
    /// [`ControllerConfig`], in one of [`CONTROLLER_TABLES`]) rather than a
    /// setting of the board (calibrations, drive, supervisor, HIL link).
    pub fn is_controller(&self) -> bool {
        CONTROLLER_TABLES.contains(&self.table())
    }

    /// `v` as it is stored: checked against the range and the type, an `f32`
    /// setting rounded to the nearest `f32` within the range.
    pub fn check(&self, v: f64) -> Result<f64, SettingsError> {
        let (lo, hi) = (self.min, self.max);
        if !(v >= lo && v <= hi) {
            return Err(SettingsError::Range);
        }
        if matches!(self.kind, ParamKind::Int | ParamKind::Bool) && libm::trunc(v) != v {
            return Err(SettingsError::NotInteger);
        }
        Ok(match self.kind {
            ParamKind::F32 => f32_within(v, lo, hi),
            _ => v,
        })
    }

    /// The value in `s` (NaN for a `Param` that is not one of [`PARAMS`]).
    pub fn get(&self, s: &Settings) -> f64 {
        let mut copy = *s;
        match self.index().and_then(|i| field(&mut copy, i)) {
            Some(f) => f.get(),
            None => f64::NAN,
        }
    }
}

/// A settable field of [`Settings`], by type.
enum Field<'a> {
    F64(&'a mut f64),
    F32(&'a mut f32),
    Usize(&'a mut usize),
    U32(&'a mut u32),
    Bool(&'a mut bool),
}

impl Field<'_> {
    fn get(&self) -> f64 {
        match self {
            Self::F64(v) => **v,
            Self::F32(v) => **v as f64,
            Self::Usize(v) => **v as f64,
            Self::U32(v) => **v as f64,
            Self::Bool(v) => {
                if **v {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }

    /// Store `v` (range-checked by the caller).
    fn set(self, v: f64) {
        match self {
            Self::F64(x) => *x = v,
            Self::F32(x) => *x = v as f32,
            Self::Usize(x) => *x = v as usize,
            Self::U32(x) => *x = v as u32,
            Self::Bool(x) => *x = v != 0.0,
        }
    }
}

/// The [`Field`] view of a settings member.
trait AsField {
    fn as_field(&mut self) -> Field<'_>;
}

macro_rules! as_field {
    ($($t:ty => $v:ident),*) => {
        $(impl AsField for $t {
            fn as_field(&mut self) -> Field<'_> {
                Field::$v(self)
            }
        })*
    };
}
as_field!(f64 => F64, f32 => F32, usize => Usize, u32 => U32, bool => Bool);

/// Defines [`PARAMS`] and the accessor `field` from one list, so that the
/// table and the fields cannot disagree.
macro_rules! params {
    ($( ($name:literal, $min:expr, $max:expr, $kind:ident, $($f:ident).+ $([$i:literal])?) ),* $(,)?) => {
        /// Every settable value, in the order of the stored image (a `static`:
        /// one copy in flash).
        pub static PARAMS: [Param; N_PARAMS] = [
            $( Param { name: $name, min: $min, max: $max, kind: ParamKind::$kind } ),*
        ];

        /// The field of parameter `i` in `s`.
        fn field(s: &mut Settings, i: usize) -> Option<Field<'_>> {
            let mut k = 0usize;
            $(
                if i == k {
                    return Some(s.$($f).+ $([$i])?.as_field());
                }
                k += 1;
            )*
            let _ = k;
            None
        }
    };
}

/// Number of settable values.
pub const N_PARAMS: usize = 80;

params! {
    // Plain MPC design.
    ("mpc.np", 1.0, 32.0, Int, controller.mpc.np),
    ("mpc.nc", 1.0, 8.0, Int, controller.mpc.nc),
    ("mpc.ts_s", 1e-3, 10.0, F64, controller.mpc.ts_s),
    ("mpc.rw", 1e-9, 1e9, F64, controller.mpc.rw),
    // MPC-ESO design.
    ("mpc_eso.np", 1.0, 32.0, Int, controller.mpc_eso.np),
    ("mpc_eso.nc", 1.0, 8.0, Int, controller.mpc_eso.nc),
    ("mpc_eso.ts_s", 1e-3, 10.0, F64, controller.mpc_eso.ts_s),
    ("mpc_eso.rw", 1e-9, 1e9, F64, controller.mpc_eso.rw),
    // Constrained MPC-ESO design (dca_core::cmpc).
    ("cmpc.np", 1.0, 100.0, Int, controller.cmpc.np),
    ("cmpc.block1", 1.0, 100.0, Int, controller.cmpc.blocks[0]),
    ("cmpc.block2", 1.0, 100.0, Int, controller.cmpc.blocks[1]),
    ("cmpc.block3", 1.0, 100.0, Int, controller.cmpc.blocks[2]),
    ("cmpc.ts_s", 1e-3, 10.0, F64, controller.cmpc.ts_s),
    ("cmpc.rw", 1e-9, 1e9, F64, controller.cmpc.rw),
    ("cmpc.a_max_mps2", 1e-3, 10000.0, F64, controller.cmpc.a_max_mps2),
    ("cmpc.load_ff", 0.0, 1.0, F64, controller.cmpc.load_ff),
    ("cmpc.preview", 0.0, 1.0, F64, controller.cmpc.preview),
    ("cmpc.comp_ff", 0.0, 1.0, F64, controller.cmpc.comp_ff),
    // Observer.
    ("eso.beta1", 0.0, 1e6, F64, controller.eso.beta1),
    ("eso.beta2", 0.0, 1e6, F64, controller.eso.beta2),
    ("eso.beta3", 0.0, 1e6, F64, controller.eso.beta3),
    ("eso.b0", -1000.0, 1000.0, F64, controller.eso.b0),
    ("eso.h_s", 1e-3, 1.0, F64, controller.eso.h_s),
    ("eso.alpha1", 1e-3, 1.0, F64, controller.eso.alpha1),
    ("eso.alpha2", 1e-3, 1.0, F64, controller.eso.alpha2),
    ("eso.delta_m", 1e-6, 1.0, F64, controller.eso.delta_m),
    // Tracking differentiator (its step is the ESO's).
    ("td.r_mps2", 1e-3, 10000.0, F32, controller.td.r_mps2),
    ("td.h0_s", 1e-4, 1.0, F32, controller.td.h0_s),
    // PI(D).
    ("pid.kp", 0.0, 10000.0, F32, controller.pid.kp),
    ("pid.ki", 0.0, 10000.0, F32, controller.pid.ki),
    ("pid.kd", 0.0, 10000.0, F32, controller.pid.kd),
    ("pid.ts_s", 1e-3, 10.0, F32, controller.pid.ts_s),
    // Fuzzy PID.
    ("fuzzy.kp", 0.0, 10000.0, F32, controller.fuzzy.base.kp),
    ("fuzzy.ki", 0.0, 10000.0, F32, controller.fuzzy.base.ki),
    ("fuzzy.kd", 0.0, 10000.0, F32, controller.fuzzy.base.kd),
    ("fuzzy.ts_s", 1e-3, 10.0, F32, controller.fuzzy.base.ts_s),
    ("fuzzy.e_span_m", 1e-6, 1.0, F32, controller.fuzzy.e_span_m),
    (
        "fuzzy.ec_span_mps",
        1e-6, 10.0,
        F32,
        controller.fuzzy.ec_span_mps
    ),
    ("fuzzy.dkp_max", 0.0, 10000.0, F32, controller.fuzzy.dkp_max),
    ("fuzzy.dki_max", 0.0, 10000.0, F32, controller.fuzzy.dki_max),
    ("fuzzy.dkd_max", 0.0, 10000.0, F32, controller.fuzzy.dkd_max),
    // Controller limits.
    (
        "limits.v_max_mps",
        1e-4, 1.0,
        F32,
        controller.limits.v_max_mps
    ),
    ("limits.x_min_m", -1.0, 1.0, F32, controller.limits.x_min_m),
    ("limits.x_max_m", -1.0, 1.0, F32, controller.limits.x_max_m),
    (
        "limits.xo_plausible_m",
        1e-3, 10.0,
        F32,
        controller.xo_plausible_m
    ),
    // Sensor calibrations: value = offset + gain * raw.
    ("cal.lvdt.gain", -1.0, 1.0, F32, cal.lvdt.gain),
    ("cal.lvdt.offset", -1.0, 1.0, F32, cal.lvdt.offset),
    ("cal.p1.gain", -1e6, 1e6, F32, cal.p1.gain),
    ("cal.p1.offset", -1e8, 1e8, F32, cal.p1.offset),
    ("cal.p2.gain", -1e6, 1e6, F32, cal.p2.gain),
    ("cal.p2.offset", -1e8, 1e8, F32, cal.p2.offset),
    ("cal.force.gain", -10000.0, 10000.0, F32, cal.force.gain),
    ("cal.force.offset", -1e6, 1e6, F32, cal.force.offset),
    ("cal.encoder.gain", -1e-3, 1e-3, F32, cal.encoder.gain),
    ("cal.encoder.offset", -1.0, 1.0, F32, cal.encoder.offset),
    // Drive.
    ("drive.duty_per_mps", 0.0, 10000.0, F32, drive.duty_per_mps),
    ("drive.invert", 0.0, 1.0, Bool, drive.invert),
    // Supervisor.
    ("sup.lvdt_min_m", -1.0, 1.0, F32, limits.lvdt_valid_m[0]),
    ("sup.lvdt_max_m", -1.0, 1.0, F32, limits.lvdt_valid_m[1]),
    ("sup.p_min_pa", -1e8, 1e8, F32, limits.p_valid_pa[0]),
    ("sup.p_valid_max_pa", -1e8, 1e8, F32, limits.p_valid_pa[1]),
    ("sup.ft_min_n", -1e6, 1e6, F32, limits.ft_valid_n[0]),
    ("sup.ft_max_n", -1e6, 1e6, F32, limits.ft_valid_n[1]),
    ("sup.p_max_pa", 0.0, 1e8, F32, limits.p_max_pa),
    ("sup.stroke_min_m", -1.0, 1.0, F32, limits.stroke_m[0]),
    ("sup.stroke_max_m", -1.0, 1.0, F32, limits.stroke_m[1]),
    ("hil.timeout_ms", 0.0, 60000.0, Int, hil_timeout_ms),
    // The design model: the rig's parameters the controllers are designed
    // on (nominal by default; `host-sim tune` sets the identified rig's),
    // with the simulator's plausible ranges (host_sim::model::params).
    ("model.m_kg", 1e-3, 1e4, F64, controller.plant.m_kg),
    ("model.ap1_m2", 1e-6, 1e-2, F64, controller.plant.ap1_m2),
    ("model.ap2_m2", 1e-6, 1e-2, F64, controller.plant.ap2_m2),
    ("model.aa1_m2", 1e-6, 1e-2, F64, controller.plant.aa1_m2),
    ("model.aa2_m2", 1e-6, 1e-2, F64, controller.plant.aa2_m2),
    ("model.c_visc_nspm", 0.0, 1e6, F64, controller.plant.c_visc_nspm),
    ("model.beta_e_pa", 1e7, 1e10, F64, controller.plant.beta_e_pa),
    ("model.tau_m_s", 1e-4, 1.0, F64, controller.plant.tau_m_s),
    ("model.p_acc0_pa", -1e5, 1e8, F64, controller.plant.p_acc0_pa),
    ("model.hose.ce0_m3pp", 1e-18, 1e-9, F64, controller.plant.hose.ce0_m3pp),
    ("model.hose.cf0_m3pp", 1e-18, 1e-9, F64, controller.plant.hose.cf0_m3pp),
    ("model.hose.cs0_m3pp", 1e-18, 1e-9, F64, controller.plant.hose.cs0_m3pp),
    ("model.hose.tau_s_s", 1e-5, 100.0, F64, controller.plant.hose.tau_s_s),
}

/// The tables of [`PARAMS`] whose values are fields of [`ControllerConfig`]
/// (the rest are the board's: `cal`, `drive`, `sup`, `hil`).
pub const CONTROLLER_TABLES: [&str; 9] = [
    "mpc", "mpc_eso", "cmpc", "eso", "td", "pid", "fuzzy", "limits", "model",
];

/// Set the controller parameter `name` of `cfg` to `v`, range- and
/// type-checked as [`Settings::set`] does (the console's table, so that a
/// configuration file, a sweep and the console accept the same paths and
/// values). `cfg` is not validated as a whole: [`Controller::new`] does that.
/// A path that is not a controller parameter is [`SettingsError::UnknownName`].
pub fn set_controller(cfg: &mut ControllerConfig, name: &str, v: f64) -> Result<(), SettingsError> {
    let p = find(name)
        .filter(|p| p.is_controller())
        .ok_or(SettingsError::UnknownName)?;
    let mut s = Settings {
        controller: *cfg,
        ..Settings::default()
    };
    s.set_checked(p, v)?;
    *cfg = s.controller;
    Ok(())
}

/// Find a parameter by its path name.
pub fn find(name: &str) -> Option<&'static Param> {
    PARAMS.iter().find(|p| p.name == name)
}

/// Why a value or an image was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SettingsError {
    /// No parameter has this name.
    UnknownName,
    /// Outside the parameter's range (or not finite).
    Range,
    /// Not a whole number (integer parameter) or not 0/1 (flag).
    NotInteger,
    /// A `[min, max]` pair is not ordered.
    Order,
    /// A controller could not be designed from the result.
    Design(dca_core::controller::ConfigError),
    /// A stored image is too short, has the wrong magic, version or layout.
    Format,
    /// A stored image's checksum does not match.
    Checksum,
}

impl SettingsError {
    /// A short human-readable reason.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::UnknownName => "unknown setting",
            Self::Range => "value out of range",
            Self::NotInteger => "value must be a whole number (0 or 1 for a flag)",
            Self::Order => "a minimum must be below its maximum",
            Self::Design(e) => e.as_str(),
            Self::Format => "stored settings have another format or version",
            Self::Checksum => "stored settings are corrupt (checksum)",
        }
    }
}

/// Image magic.
const MAGIC: [u8; 4] = *b"DCAS";
/// Image format version (the header layout; the table is covered by the
/// layout CRC).
const FORMAT_VERSION: u16 = 1;
/// Header bytes before the values.
const HEADER_LEN: usize = 16;

/// Length of the stored image, bytes (a multiple of 4).
pub const IMAGE_LEN: usize = HEADER_LEN + 8 * PARAMS.len() + 4;

const CRC32: crc::Crc<u32, crc::NoTable> =
    crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// CRC-32 of the parameter names in table order: identifies the table.
pub fn layout_crc() -> u32 {
    let mut d = CRC32.digest();
    for p in &PARAMS {
        d.update(p.name.as_bytes());
        d.update(&[0]);
    }
    d.finalize()
}

/// `v` (within `[lo, hi]`) as the `f32` it is stored as, kept within
/// `[lo, hi]`: a bound that is not an `f32` (1e-4, 1e-3, ...) can round to
/// the `f32` just outside it, which the range check of the stored image
/// would then refuse; the neighbouring `f32` inside is taken instead.
fn f32_within(v: f64, lo: f64, hi: f64) -> f64 {
    let x = v as f32;
    let x = if (x as f64) < lo {
        x.next_up()
    } else if (x as f64) > hi {
        x.next_down()
    } else {
        x
    };
    x as f64
}

fn kind_code(k: ControllerKind) -> u8 {
    ControllerKind::ALL
        .iter()
        .position(|x| *x == k)
        .unwrap_or(0) as u8
}

impl Settings {
    /// A controller preset with the nominal calibrations, drive scaling and
    /// limits, at the board's base tick.
    pub fn preset(preset: Preset, kind: ControllerKind) -> Self {
        let mut controller = ControllerConfig::preset(preset, kind);
        controller.base_dt_s = BOARD_DT_S;
        let mut s = Self {
            controller,
            limits: SupervisorLimits::DEFAULT,
            cal: Calibration::nominal(),
            drive: DriveScale::DEFAULT,
            hil_timeout_ms: 100,
        };
        s.normalise();
        s
    }

    /// These settings with the controller parameters of `preset` (kind,
    /// calibrations, drive and limits kept).
    pub fn with_preset(&self, preset: Preset) -> Self {
        let fresh = Self::preset(preset, self.controller.kind);
        Self {
            controller: fresh.controller,
            ..*self
        }
    }

    /// These settings running another controller kind.
    pub fn with_kind(&self, kind: ControllerKind) -> Self {
        let mut s = *self;
        s.controller.kind = kind;
        s
    }

    /// The value at `name`.
    pub fn get(&self, name: &str) -> Result<f64, SettingsError> {
        find(name)
            .map(|p| p.get(self))
            .ok_or(SettingsError::UnknownName)
    }

    /// Set `name` to `v`, range- and type-checked, without validating the
    /// whole: after several changes, call [`Settings::validate`] once. An
    /// `f32` setting stores the nearest `f32` within its range.
    pub fn set(&mut self, name: &str, v: f64) -> Result<(), SettingsError> {
        let p = find(name).ok_or(SettingsError::UnknownName)?;
        self.set_checked(p, v)
    }

    fn set_checked(&mut self, p: &Param, v: f64) -> Result<(), SettingsError> {
        let v = p.check(v)?;
        match p.index().and_then(|i| field(self, i)) {
            Some(f) => f.set(v),
            None => return Err(SettingsError::UnknownName),
        }
        self.normalise();
        Ok(())
    }

    /// The TD runs at the ESO's step (`Controller::new` uses `eso.h_s`); keep
    /// the copy in `td.h_s` equal so that equal settings compare equal.
    fn normalise(&mut self) {
        self.controller.td.h_s = self.controller.eso.h_s as f32;
    }

    /// A copy with `name` set to `v`, range-checked, validated as a whole
    /// (see [`Settings::validate`]); `self` is never changed. An `f32`
    /// setting stores the nearest `f32` within its range.
    pub fn with(&self, name: &str, v: f64) -> Result<(Self, Controller), SettingsError> {
        let p = find(name).ok_or(SettingsError::UnknownName)?;
        let mut s = *self;
        s.set_checked(p, v)?;
        let c = s.validate()?;
        Ok((s, c))
    }

    /// Check the limit pairs and design every controller kind from these
    /// settings; returns the selected kind's controller (fresh state).
    pub fn validate(&self) -> Result<Controller, SettingsError> {
        let l = &self.limits;
        let ordered = |r: [f32; 2]| r[0] < r[1];
        if !(ordered(l.lvdt_valid_m)
            && ordered(l.p_valid_pa)
            && ordered(l.ft_valid_n)
            && ordered(l.stroke_m))
        {
            return Err(SettingsError::Order);
        }
        // Every law's parameters, not only the selected one's, so that a later
        // `controller` command cannot meet an invalid set.
        let c = &self.controller;
        let design = |e| SettingsError::Design(ConfigError::Design(e));
        MpcGains::design(&c.plant, c.mpc).map_err(design)?;
        MpcGains::design(&c.plant, c.mpc_eso).map_err(design)?;
        CmpcGains::design(&c.plant, c.cmpc, &c.limits, c.base_dt_s).map_err(design)?;
        EsoFixedGains::new(&c.eso).map_err(|e| SettingsError::Design(ConfigError::Eso(e)))?;
        if !c.td.is_valid() {
            return Err(SettingsError::Design(ConfigError::Td));
        }
        if !(c.pid.is_valid() && c.fuzzy.is_valid()) {
            return Err(SettingsError::Design(ConfigError::Pid));
        }
        Controller::new(c).map_err(SettingsError::Design)
    }

    /// The stored image (see the module documentation).
    pub fn to_image(&self) -> [u8; IMAGE_LEN] {
        let mut img = [0u8; IMAGE_LEN];
        img[0..4].copy_from_slice(&MAGIC);
        img[4..6].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
        img[6..8].copy_from_slice(&(PARAMS.len() as u16).to_le_bytes());
        img[8..12].copy_from_slice(&layout_crc().to_le_bytes());
        img[12] = kind_code(self.controller.kind);
        for (i, p) in PARAMS.iter().enumerate() {
            let at = HEADER_LEN + 8 * i;
            img[at..at + 8].copy_from_slice(&p.get(self).to_le_bytes());
        }
        let n = IMAGE_LEN - 4;
        let crc = CRC32.checksum(&img[..n]);
        img[n..].copy_from_slice(&crc.to_le_bytes());
        img
    }

    /// Read an image: format, checksum, every value's range and the whole
    /// result are checked, and the image must be exactly what
    /// [`Settings::to_image`] writes for the result (bytes past
    /// [`IMAGE_LEN`] are not read); on any failure nothing is returned.
    pub fn from_image(img: &[u8]) -> Result<(Self, Controller), SettingsError> {
        if img.len() < IMAGE_LEN
            || img[0..4] != MAGIC
            || img[4..6] != FORMAT_VERSION.to_le_bytes()
            || img[6..8] != (PARAMS.len() as u16).to_le_bytes()
        {
            return Err(SettingsError::Format);
        }
        let n = IMAGE_LEN - 4;
        if CRC32.checksum(&img[..n]).to_le_bytes() != img[n..IMAGE_LEN] {
            return Err(SettingsError::Checksum);
        }
        if img[8..12] != layout_crc().to_le_bytes() {
            return Err(SettingsError::Format);
        }
        let kind = *ControllerKind::ALL
            .get(img[12] as usize)
            .ok_or(SettingsError::Format)?;
        let mut s = Self::default().with_kind(kind);
        for (i, p) in PARAMS.iter().enumerate() {
            let at = HEADER_LEN + 8 * i;
            let mut b = [0u8; 8];
            b.copy_from_slice(&img[at..at + 8]);
            s.set_checked(p, f64::from_le_bytes(b))?;
        }
        // Only what `to_image` writes is read: non-zero padding, an `f32`
        // setting stored with more precision than an `f32`, or a whole number
        // stored as -0 is another format, not these settings.
        if img.get(..IMAGE_LEN) != Some(&s.to_image()[..]) {
            return Err(SettingsError::Format);
        }
        let c = s.validate()?;
        Ok((s, c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reseal(img: &mut [u8; IMAGE_LEN]) {
        let n = IMAGE_LEN - 4;
        let crc = CRC32.checksum(&img[..n]);
        img[n..].copy_from_slice(&crc.to_le_bytes());
    }

    fn with_value(name: &str, v: f64) -> [u8; IMAGE_LEN] {
        let i = PARAMS.iter().position(|p| p.name == name).unwrap();
        let mut img = Settings::default().to_image();
        img[HEADER_LEN + 8 * i..][..8].copy_from_slice(&v.to_le_bytes());
        reseal(&mut img);
        img
    }

    /// Found by fuzzing the console: `set td.h0_s 0.0001` stored the `f32`
    /// just below the bound 1e-4, so `store` wrote an image that `load` (and
    /// the next boot) refused as out of range.
    #[test]
    fn f32_settings_at_a_bound_stay_in_range_and_load_back() {
        for (name, v) in [
            ("td.h0_s", 1e-4),
            ("limits.v_max_mps", 1e-4),
            ("fuzzy.e_span_m", 1e-6),
            ("cal.encoder.gain", 1e-3),
            ("cal.encoder.gain", -1e-3),
        ] {
            let (s, _) = Settings::default().with(name, v).unwrap();
            let p = find(name).unwrap();
            let got = p.get(&s);
            assert!(got >= p.min && got <= p.max, "{name} = {got:e}");
            // At most one f32 step away.
            assert!(
                (got - v).abs() <= v.abs() * f32::EPSILON as f64,
                "{name} = {got:e}"
            );
            let (back, _) = Settings::from_image(&s.to_image()).unwrap();
            assert_eq!(back, s, "{name}");
        }
        // Values inside the range keep their nearest f32.
        let (s, _) = Settings::default().with("pid.kp", 0.1).unwrap();
        assert_eq!(s.controller.pid.kp, 0.1f32);
    }

    /// A controller configuration set by path changes exactly the field the
    /// console's `set` changes, for every controller parameter; the board's
    /// settings are not controller parameters.
    #[test]
    fn controller_paths_are_the_console_paths() {
        let mut n = 0;
        for p in &PARAMS {
            let mut cfg = ControllerConfig::preset(Preset::Fast, ControllerKind::Pid);
            // A value inside the range that differs from the preset's.
            let v = match p.kind {
                ParamKind::Int | ParamKind::Bool => p.max,
                _ => 0.5 * p.min + 0.5 * p.max,
            };
            let r = set_controller(&mut cfg, p.name, v);
            if !p.is_controller() {
                assert_eq!(r, Err(SettingsError::UnknownName), "{}", p.name);
                continue;
            }
            n += 1;
            r.unwrap();
            let mut console = Settings::preset(Preset::Fast, ControllerKind::Pid);
            console.controller.base_dt_s = cfg.base_dt_s;
            console.set(p.name, v).unwrap();
            assert_eq!(console.controller, cfg, "{}", p.name);
            assert_eq!(p.get(&console), p.check(v).unwrap(), "{}", p.name);
            assert_eq!(&p.name[..p.table().len()], p.table());
            assert_eq!(&p.name[p.table().len() + 1..], p.key());
        }
        assert_eq!(n, 58);
        let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::Mpc);
        let before = cfg;
        assert_eq!(
            set_controller(&mut cfg, "mpc.np", 6.5),
            Err(SettingsError::NotInteger)
        );
        assert_eq!(
            set_controller(&mut cfg, "mpc.rw", 1e10),
            Err(SettingsError::Range)
        );
        assert_eq!(cfg, before, "a refused value changes nothing");
    }

    /// Found by fuzzing the image: images `to_image` never writes were read.
    #[test]
    fn only_canonical_images_are_read() {
        let mut padding = Settings::default().to_image();
        padding[13] = 1;
        reseal(&mut padding);
        assert_eq!(
            Settings::from_image(&padding).unwrap_err(),
            SettingsError::Format
        );
        // An f32 setting with more precision than an f32.
        assert_eq!(
            Settings::from_image(&with_value("pid.kp", 0.1)).unwrap_err(),
            SettingsError::Format
        );
        let (s, _) = Settings::from_image(&with_value("pid.kp", 0.1f32 as f64)).unwrap();
        assert_eq!(s.controller.pid.kp, 0.1f32);
        // A whole number stored as -0.
        assert_eq!(
            Settings::from_image(&with_value("hil.timeout_ms", -0.0)).unwrap_err(),
            SettingsError::Format
        );
        let (s, _) = Settings::from_image(&with_value("hil.timeout_ms", 0.0)).unwrap();
        assert_eq!(s.hil_timeout_ms, 0);
        // Bytes past the image are not read.
        let mut longer = Settings::default().to_image().to_vec();
        longer.extend_from_slice(&[0xff; 8]);
        assert!(Settings::from_image(&longer).is_ok());
    }
}

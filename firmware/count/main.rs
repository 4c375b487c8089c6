//! dca-count: the instruction-count harness of `dca_core::controller::Controller::step`.
//!
//! Not the board image: a separate binary of the dca-firmware package, built only with
//! the `count` feature (`required-features`), with the board's profile (`firmware`) and
//! target, so that dca-core is compiled as on the board. `firmware/count/count.py`
//! loads the ELF into the unicorn engine and calls the entry points below
//! directly (AAPCS: arguments in r0-r3 / s0-s1, result in r0(-r1) / s0); nothing here runs
//! on hardware. The controller lives in memory the caller owns (a pointer argument),
//! so the harness needs no mutable static.
//!
//! The controllers are designed exactly as the board designs its factory settings:
//! `Settings::preset(Preset::Paper, kind).controller` (1 kHz base tick); the
//! constrained MPC-ESO, beyond the paper, with its own preset `limit`.
#![no_std]
#![no_main]

use core::mem::MaybeUninit;
use dca_app::record::{PackedRow, Recorder};
use dca_app::settings::{Calibration, Settings};
use dca_core::controller::{Controller, ControllerKind, Preset, Sample};
// The interrupt vectors cortex-m-rt's `link.x` expects from the device crate.
use stm32f4 as _;

/// `size_of::<Controller>()`: the caller reserves this many bytes (8-aligned) for
/// [`count_init`] and [`count_step`].
// `no_mangle` is what makes the symbol findable by name; it is the only reason for
// the `unsafe_code` allowance (the function itself is safe).
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn count_controller_size() -> u32 {
    core::mem::size_of::<Controller>() as u32
}

/// Design controller `kind` (index into `ControllerKind::ALL`: 0 MPC-ESO, 1 MPC,
/// 2 PID, 3 fuzzy PID, 4 constrained MPC-ESO) from the board's factory settings
/// into `slot`. Returns 1 on
/// success, 0 for an unknown kind or a refused design (the slot is then untouched).
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn count_init(kind: u32, slot: &mut MaybeUninit<Controller>) -> u32 {
    let Some(&kind) = ControllerKind::ALL.get(kind as usize) else {
        return 0;
    };
    let preset = match kind {
        ControllerKind::CmpcEso => Preset::Limit,
        _ => Preset::Paper,
    };
    let cfg = Settings::preset(preset, kind).controller;
    match Controller::new(&cfg) {
        Ok(c) => {
            slot.write(c);
            1
        }
        Err(_) => 0,
    }
}

/// One control tick: `Controller::step` with Xo = `xo_m` and the reference `ref_m`
/// (the other sensor fields 0, as in the paper's scenarios, which start at rest at 0).
/// Returns the drive command, m/s. `ctl` must have been filled by [`count_init`].
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn count_step(ctl: &mut Controller, xo_m: f32, ref_m: f32) -> f32 {
    let sample = Sample {
        xo_m,
        ..Sample::default()
    };
    ctl.step(&sample, ref_m).v_cmd_mps
}

/// The task periods of `ctl` in base ticks: ESO/TD period n_h in the low word, the
/// controller period n_c in the high word (r0 and r1).
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn count_periods(ctl: &Controller) -> u64 {
    let (n_h, n_c) = ctl.periods();
    n_h as u64 | (n_c as u64) << 32
}

/// Rows of the record the harness counts with (two blocks of 32, as the board's
/// record spans main SRAM and the CCM RAM).
pub const COUNT_RECORD_ROWS: usize = 64;

/// `size_of::<Recorder>()`: the caller reserves this many bytes (8-aligned) for
/// [`count_record_init`].
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn count_recorder_size() -> u32 {
    core::mem::size_of::<Recorder<'static>>() as u32
}

/// A recorder over `rows` (the caller's memory, [`COUNT_RECORD_ROWS`] rows) into
/// `slot`, armed for all its rows with the factory calibration.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn count_record_init(
    slot: &mut MaybeUninit<Recorder<'static>>,
    rows: &'static mut [PackedRow; COUNT_RECORD_ROWS],
) {
    let (a, b) = rows.split_at_mut(COUNT_RECORD_ROWS / 2);
    let mut r = Recorder::new(a, b);
    // Cannot fail: 1 <= rows <= capacity.
    let _ = r.arm(COUNT_RECORD_ROWS as u32, &Calibration::nominal(), 0);
    slot.write(r);
}

/// The record's part of a control tick ([`Recorder::push`], as the control task
/// calls it with the tick's reference, command and sample), the recorder
/// re-armed first when full so that every call records a row.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn count_record_push(rec: &mut Recorder<'static>, xo_m: f32, ref_m: f32) {
    let sample = Sample {
        xo_m,
        xi_m: xo_m,
        p1_pa: 2.0e6,
        p2_pa: 1.0e6,
        ft_n: -500.0,
    };
    rec.push(true, ref_m, ref_m - xo_m, &sample, 0);
}

/// Re-arm the recorder (between counted calls, when it is full).
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn count_record_rearm(rec: &mut Recorder<'static>) {
    let _ = rec.arm(COUNT_RECORD_ROWS as u32, &Calibration::nominal(), 0);
}

/// Never run: it only keeps the entry points in the image (a linked executable exports
/// nothing, so the linker would drop them otherwise).
#[cortex_m_rt::entry]
fn main() -> ! {
    core::hint::black_box(count_controller_size as extern "C" fn() -> u32);
    core::hint::black_box(count_init as extern "C" fn(u32, &mut MaybeUninit<Controller>) -> u32);
    core::hint::black_box(count_step as extern "C" fn(&mut Controller, f32, f32) -> f32);
    core::hint::black_box(count_periods as extern "C" fn(&Controller) -> u64);
    core::hint::black_box(count_recorder_size as extern "C" fn() -> u32);
    core::hint::black_box(
        count_record_init
            as extern "C" fn(
                &mut MaybeUninit<Recorder<'static>>,
                &'static mut [PackedRow; COUNT_RECORD_ROWS],
            ),
    );
    core::hint::black_box(count_record_push as extern "C" fn(&mut Recorder<'static>, f32, f32));
    core::hint::black_box(count_record_rearm as extern "C" fn(&mut Recorder<'static>));
    loop {
        cortex_m::asm::wfi();
    }
}

/// A panic ends in `udf`, which the emulator reports as an exception.
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    cortex_m::asm::udf()
}

//! dca-app: the board application the control laws of `dca-core` run in.
//!
//! What a board needs around the laws, written once for the firmware, the
//! simulator's HIL runs and the tests:
//!
//! * [`supervisor`]: the states (idle, armed, running, fault), the fault
//!   checks on every sample, and [`supervisor::ControlLoop`], the per-tick
//!   sequence (checks, reference, controller step, gating of the command);
//! * [`settings`]: every settable value (controller parameters, sensor
//!   calibrations, drive scaling, limits) by path name with its range, and the
//!   stored image with its version and checksum;
//! * [`console`]: the serial console (its receive path, the line editor, the
//!   command set) without I/O;
//! * [`frame`]: the HIL link's frames and the link supervision;
//! * [`record`]: the on-board record of every control tick and its dump;
//! * [`text`]: decimal numbers in and out without `core::fmt`'s float code.
//!
//! Layers: this crate depends on `dca-core`, never the reverse. It is
//! `no_std`, allocation-free and forbids `unsafe`, like the laws.
#![no_std]
#![forbid(unsafe_code)]

pub mod console;
pub mod frame;
pub mod record;
pub mod settings;
pub mod supervisor;
pub mod text;

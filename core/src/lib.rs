//! dca-core: the control laws of the miniature double-cylinder hydraulic
//! actuator.
//!
//! Everything that decides a drive command lives here, for the firmware, the
//! simulator and the hardware-in-the-loop runs alike (docs/model.md section 6):
//!
//! * [`design`]: prediction model, ZOH, augmented model and MPC gains (f64,
//!   nalgebra, no allocation), so the board can re-design after a change;
//! * [`mpc`], [`td`], [`pid`], [`fuzzy`]: the per-tick laws in f32;
//! * [`cmpc`]: the constrained MPC-ESO, a box-constrained quadratic program
//!   solved every period at a fixed, data-independent cost;
//! * [`eso`]: the extended state observer in fixed point ([`fxp`]) with its
//!   binary64 reference;
//! * [`controller`]: the multi-rate schedule behind one `step` call, the
//!   presets "paper" and "fast", and the input guards.
//!
//! The board application these laws run in (supervisor, settings and
//! calibrations, console, HIL frames) is the separate crate `dca-app`
//! (`core/app/`), which depends on this one and never the other way: the laws
//! know nothing of where their samples come from.
//!
//! The crate is `no_std`, allocation-free and forbids `unsafe`. Determinism:
//! only IEEE-754 +, -, *, /, sqrt and `libm` functions are used (no fused or
//! target-specific operations), and the observer is pure integer arithmetic,
//! so the same inputs give bit-identical outputs on x86-64 and on thumbv7em.
#![no_std]
#![forbid(unsafe_code)]

pub mod cmpc;
pub mod controller;
pub mod design;
pub mod eso;
pub mod fuzzy;
pub mod fxp;
pub mod mpc;
pub mod params;
pub mod pid;
pub mod td;

pub use controller::{
    ConfigError, Controller, ControllerConfig, ControllerKind, Flags, Output, Preset, Sample,
};

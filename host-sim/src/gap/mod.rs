//! `host-sim gap`: where a recorded run departs from the nominal model, which
//! unmodelled effect causes it, and how far the gap shrinks once that effect
//! is added, checked on held-out runs (interfaces.md section 2).

pub mod diagnose;
pub mod fit;
pub mod replay;
pub mod segment;
pub mod stats;

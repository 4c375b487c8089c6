//! Cross-crate system tests live in `tests/tests/`.

pub mod foreign;

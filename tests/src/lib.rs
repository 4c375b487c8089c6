//! Cross-crate system tests live in `tests/tests/`.

pub mod foreign;
pub mod fourth;
pub mod fuzz;
pub mod third;

//! Layer `io` (the bottom): file formats and output helpers.
//!
//! * [`runlog`]: the run-log CSV format of docs/interfaces.md section 1, written and read;
//! * [`plot`]: PNG figures for the reports;
//! * [`bars`]: PNG bar charts with named categories;
//! * [`files`]: reading and writing files with errors that name the path;
//! * [`num`]: numbers in messages in a readable form;
//! * [`toml_key`]: TOML table keys read through a lookup, errors at the key's line.
//!
//! Imports nothing from the crate: every other layer may use it.

pub mod bars;
pub mod files;
pub mod num;
pub mod plot;
pub mod runlog;
pub mod toml_key;

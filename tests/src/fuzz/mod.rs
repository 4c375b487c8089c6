//! Fuzz harnesses: one function per input that reaches the project from
//! untrusted bytes. Each takes arbitrary bytes, drives the real code with them
//! and panics when an invariant breaks.
//!
//! The same functions run under cargo-fuzz (`tests/fuzz/`, nightly, libFuzzer)
//! and on stable in `cargo test` (`tests/tests/fuzz_corpus.rs`: the seed
//! corpus, the regressions and a fixed-seed pseudo-random sweep), so a harness
//! can never rot unnoticed. `docs/fuzzing.md` lists the invariants.
//!
//! | harness | code under test |
//! |---|---|
//! | [`console()`] | `dca_app::console`: line editor and command interpreter, settings store/load |
//! | [`console_rx()`] | `dca_app::console::Receiver`: the receive path between the byte interrupt and the console task |
//! | [`frame()`] | `dca_app::frame`: HIL frame reader, decoder and link monitor |
//! | [`settings_image()`] | `dca_app::settings::Settings::from_image` |
//! | [`runlog()`] | `host_sim::io::runlog::RunLog::parse` |
//! | [`scenario_toml()`] | `host_sim::sim::config::ScenarioFile::load_str`, effects, controller tables |
//! | [`config_toml()`] | `host_sim::sim::config::ConfigFile` and `host_sim::sim::batch::SweepParam::parse` |
//!
//! # Known defects
//! A defect that is found but must be fixed outside the files this harness
//! owns is reported through [`known_defect`]: it panics when the environment
//! variable `DCA_FUZZ_STRICT` is `1` (to minimise a reproducer, or to check a
//! fix) and is otherwise counted, so that fuzzing goes on finding new defects.
//! Every other broken invariant panics.

use std::cell::RefCell;
use std::sync::OnceLock;

pub mod config_toml;
pub mod console;
pub mod console_rx;
pub mod frame;
pub mod runlog;
pub mod scenario_toml;
pub mod seeds;
pub mod settings_image;

pub use config_toml::config_toml;
pub use console::console;
pub use console_rx::console_rx;
pub use frame::frame;
pub use runlog::runlog;
pub use scenario_toml::scenario_toml;
pub use settings_image::settings_image;

/// A harness: arbitrary bytes in, a panic on a broken invariant.
pub type Harness = fn(&[u8]);

/// Every harness by target name (the cargo-fuzz target, and the directory of
/// its seeds under `tests/fuzz/corpus/`).
pub const TARGETS: [(&str, Harness); 7] = [
    ("console", console),
    ("console_rx", console_rx),
    ("frame", frame),
    ("settings_image", settings_image),
    ("runlog", runlog),
    ("scenario_toml", scenario_toml),
    ("config_toml", config_toml),
];

/// The harness of the target called `name`.
pub fn harness(name: &str) -> Option<Harness> {
    TARGETS.iter().find(|(n, _)| *n == name).map(|(_, h)| *h)
}

fn strict() -> bool {
    static STRICT: OnceLock<bool> = OnceLock::new();
    *STRICT.get_or_init(|| std::env::var("DCA_FUZZ_STRICT").is_ok_and(|v| v == "1"))
}

thread_local! {
    static KNOWN: RefCell<Vec<&'static str>> = const { RefCell::new(Vec::new()) };
}

/// A documented defect whose fix lies outside the harness's files was hit:
/// panic under `DCA_FUZZ_STRICT=1`, else remember `id` for
/// [`take_known_defects`].
pub fn known_defect(id: &'static str, detail: &str) {
    if strict() {
        panic!("known defect {id}: {detail}");
    }
    KNOWN.with(|k| {
        let mut k = k.borrow_mut();
        if !k.contains(&id) {
            k.push(id);
        }
    });
}

/// The known defects hit on this thread since the last call (and forget them).
pub fn take_known_defects() -> Vec<&'static str> {
    KNOWN.with(|k| std::mem::take(&mut *k.borrow_mut()))
}

/// Reads fuzz input as a stream of small values; past the end every read
/// gives zeros, so any input is a complete program.
#[derive(Clone, Debug)]
pub struct Bytes<'a> {
    data: &'a [u8],
}

impl<'a> Bytes<'a> {
    /// A reader over `data`.
    pub fn new(data: &'a [u8]) -> Self {
        Self { data }
    }

    /// True when every byte was read.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// The next byte (0 past the end).
    pub fn u8(&mut self) -> u8 {
        match self.data.split_first() {
            Some((b, rest)) => {
                self.data = rest;
                *b
            }
            None => 0,
        }
    }

    /// The next two bytes, little-endian.
    pub fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }

    /// The next four bytes, little-endian.
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }

    /// The next eight bytes, little-endian.
    pub fn u64(&mut self) -> u64 {
        u64::from(self.u32()) | (u64::from(self.u32()) << 32)
    }

    /// Everything not read yet.
    pub fn rest(&mut self) -> &'a [u8] {
        std::mem::take(&mut self.data)
    }
}

/// The input as text: valid UTF-8 as it is, anything else with U+FFFD for
/// the invalid sequences (text loaders only ever see `&str`).
pub fn text(data: &[u8]) -> std::borrow::Cow<'_, str> {
    String::from_utf8_lossy(data)
}

/// Number of lines `str::lines` sees in `text`, plus one (a position just
/// past the last line is still a fair error position).
pub fn line_limit(text: &str) -> usize {
    text.lines().count() + 1
}

/// CRC-32/ISO-HDLC (the settings image's checksum), bit by bit: lets a
/// harness re-seal an image it corrupted, so that the corruption reaches the
/// checks behind the checksum.
pub fn crc32_iso_hdlc(data: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// CRC-16/IBM-3740 (the HIL frames' checksum), bit by bit.
pub fn crc16_ibm_3740(data: &[u8]) -> u16 {
    let mut crc = 0xffffu16;
    for &b in data {
        crc ^= u16::from(b) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

//! Puts the workspace's `memory.x` (the one source of the memory map) on the linker
//! search path, where cortex-m-rt's `link.x` finds it, and writes `record_region.x`,
//! which memory.x includes: the region of the on-board record's second block.
//!
//! That region is the CCM RAM on the board. The emulated build (feature `qemu`) has
//! none: QEMU 7.2's `netduinoplus2` emulates no CCM RAM at 0x10000000 but 192 KiB of
//! SRAM from 0x20000000, so there the block is the 64 KiB after the board's 128 KiB
//! (same size, same code).

use std::{env, fs, path::PathBuf};

const BOARD: &str = "REGION_ALIAS(\"RECORD_CCM\", CCMRAM);\n";
const QEMU: &str = "MEMORY\n{\n  QEMU_SRAM_TOP : ORIGIN = 0x20020000, LENGTH = 64K\n}\n\
                    REGION_ALIAS(\"RECORD_CCM\", QEMU_SRAM_TOP);\n";

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let memory_x = manifest.join("..").join("memory.x");
    fs::copy(&memory_x, out.join("memory.x"))
        .unwrap_or_else(|e| panic!("copy {}: {e}", memory_x.display()));
    let region = if env::var_os("CARGO_FEATURE_QEMU").is_some() {
        QEMU
    } else {
        BOARD
    };
    fs::write(out.join("record_region.x"), region)
        .unwrap_or_else(|e| panic!("write record_region.x: {e}"));
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");
}

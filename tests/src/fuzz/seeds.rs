//! The generated part of the seed corpus: inputs with binary headers or
//! binary content (console sessions with their fault plan, HIL frames,
//! settings images). The text seeds (run logs, TOML) are plain files in
//! `tests/fuzz/corpus/`.
//!
//! `tests/tests/fuzz_corpus.rs` checks that the files on disk are what these
//! functions make (so a change of the frame or image format cannot leave the
//! fuzzers starting from stale seeds) and rewrites them when run with
//! `DCA_FUZZ_WRITE_SEEDS=1`.

use dca_app::frame::{encode, SampleFrame, MAX_FRAME_LEN};
use dca_app::settings::{Settings, IMAGE_LEN};
use dca_core::controller::{ControllerKind, Preset};

/// One generated seed: target, file name, content.
pub type Seed = (&'static str, &'static str, Vec<u8>);

/// File-name prefix of generated seeds (the other seeds are hand-written).
pub const PREFIX: &str = "gen-";

/// A console session: the fault plan `[mode, pos lo, pos hi, mask]`, then
/// the lines, each ended by CR LF.
fn session(plan: [u8; 4], lines: &[&str]) -> Vec<u8> {
    let mut v = plan.to_vec();
    for l in lines {
        v.extend_from_slice(l.as_bytes());
        v.extend_from_slice(b"\r\n");
    }
    v
}

/// Byte `k` of the value of parameter `i` in a settings image.
fn value_byte(i: usize, k: usize) -> [u8; 2] {
    ((16 + 8 * i + k) as u16).to_le_bytes()
}

fn console_seeds() -> Vec<Seed> {
    let mut v = console_command_seeds();
    v.extend(console_line_and_flash_seeds());
    v
}

/// Console sessions of commands: queries, settings, motion, faults, refused
/// commands.
fn console_command_seeds() -> Vec<Seed> {
    vec![
        (
            "console",
            "gen-queries",
            session(
                [0, 0, 0, 0],
                &[
                    "help",
                    "status",
                    "get",
                    "get eso.beta1",
                    "get cal.encoder.gain",
                    "controller",
                    "fault",
                    "ping",
                    "ping abc",
                ],
            ),
        ),
        (
            "console",
            "gen-settings-store-load",
            session(
                [0, 0, 0, 0],
                &[
                    "set mpc_eso.rw 300",
                    "set pid.kp 3.5",
                    "set sup.stroke_max_m 0.1",
                    "set hil.timeout_ms 250",
                    "set drive.invert 1",
                    "controller pid",
                    "preset fast",
                    "store",
                    "defaults",
                    "load",
                    "get mpc_eso.rw",
                ],
            ),
        ),
        (
            "console",
            "gen-motion",
            session(
                [0x10, 0, 0, 0],
                &[
                    "arm",
                    "goto 10",
                    "stop",
                    "sine 20 0.5",
                    "telemetry on 10",
                    "status",
                    "set pid.kp 3",
                    "hil on",
                    "telemetry off",
                    "disarm",
                    "hil on",
                    "echo on",
                ],
            ),
        ),
        (
            "console",
            "gen-faults",
            session(
                [0x20, 0, 0, 0],
                &["arm", "fault", "goto 5", "clear", "status", "clear"],
            ),
        ),
        (
            "console",
            "gen-refused",
            session(
                [0, 0, 0, 0],
                &[
                    "frobnicate",
                    "set",
                    "set eso.beta1 abc",
                    "set eso.beta1 1e999",
                    "set eso.beta1 -5",
                    "set mpc_eso.np 8.5",
                    "set mpc.np 1",
                    "set sup.stroke_min_m 0.5",
                    "get no.such",
                    "goto 500",
                    "sine 80 1",
                    "controller lqr",
                    "preset slow",
                    "telemetry on 5",
                    "telemetry on 1.5",
                    "load",
                    "clear",
                    "stop",
                ],
            ),
        ),
    ]
}

/// Console sessions that exercise the line editor, lost bytes and the flash.
fn console_line_and_flash_seeds() -> Vec<Seed> {
    let beta1_exp = value_byte(8, 7);
    vec![
        ("console", "gen-editing", {
            let mut v = session([0, 0, 0, 0], &["hlep\x08\x08elp", "\x01status", "", ""]);
            v.extend_from_slice(&[b'x'; 90]);
            v.extend_from_slice(b"\r\nget\x7f\x7f\x7fstatus\n\r\n\xc3\xa9\r\n");
            v
        }),
        (
            "console",
            "gen-overrun",
            session([0x08, 0, 0, 3], &["status", "get pid.kp", "help"]),
        ),
        (
            "console",
            "gen-flash-flip",
            session([0x01, 40, 0, 0x01], &["store", "load", "status"]),
        ),
        (
            "console",
            "gen-flash-sealed-value",
            session(
                [0x02, beta1_exp[0], beta1_exp[1], 0x40],
                &["store", "load", "get eso.beta1"],
            ),
        ),
        (
            "console",
            "gen-flash-sealed-kind",
            session([0x06, 12, 0, 0x01], &["load", "controller", "load"]),
        ),
        (
            "console",
            "gen-flash-write-fails",
            session([0x07, 0, 0, 0], &["store", "load"]),
        ),
    ]
}

fn sample(seq: u32) -> SampleFrame {
    SampleFrame {
        seq,
        ref_m: 0.05,
        xo_m: 0.012_345_678,
        xi_m: 0.012,
        p1_pa: 640_127.4,
        p2_pa: 1.0e6,
        ft_n: 400.0,
    }
}

fn wire(f: &SampleFrame) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME_LEN];
    let n = encode(f, &mut out).expect("a sample frame fits");
    out[..n].to_vec()
}

/// A structured frame case: the message's 28 bytes, the mode, corruptions.
fn structured(f: &SampleFrame, mode: u8, ops: &[[u8; 3]]) -> Vec<u8> {
    let mut v = vec![1u8];
    v.extend_from_slice(&f.seq.to_le_bytes());
    for x in [f.ref_m, f.xo_m, f.xi_m, f.p1_pa, f.p2_pa, f.ft_n] {
        v.extend_from_slice(&x.to_bits().to_le_bytes());
    }
    v.push(mode);
    for op in ops {
        v.extend_from_slice(op);
    }
    v
}

fn frame_seeds() -> Vec<Seed> {
    let stream = |frames: &[Vec<u8>]| {
        let mut v = vec![0u8, 0u8];
        for f in frames {
            v.extend_from_slice(f);
        }
        v
    };
    let mut flipped = wire(&sample(1));
    flipped[5] ^= 0x10;
    let weird = SampleFrame {
        seq: u32::MAX,
        ref_m: f32::NAN,
        xo_m: f32::MIN_POSITIVE / 2.0,
        xi_m: f32::INFINITY,
        p1_pa: f32::MAX,
        p2_pa: -0.0,
        ft_n: 1.0e-38,
    };
    vec![
        (
            "frame",
            "gen-stream-valid",
            stream(&[wire(&sample(0)), wire(&sample(1)), wire(&sample(2))]),
        ),
        (
            "frame",
            "gen-stream-gap-and-repeat",
            stream(&[
                wire(&sample(0)),
                wire(&sample(2)),
                wire(&sample(1)),
                wire(&sample(1)),
            ]),
        ),
        (
            "frame",
            "gen-stream-noise-before-start",
            stream(&[
                b"dca-firmware ready\r\n\0".to_vec(),
                wire(&sample(7)),
                wire(&sample(0)),
                wire(&sample(1)),
            ]),
        ),
        (
            "frame",
            "gen-stream-overlong",
            stream(&[wire(&sample(0)), vec![0x11; 70], vec![0], wire(&sample(1))]),
        ),
        (
            "frame",
            "gen-stream-corrupt",
            stream(&[wire(&sample(0)), flipped, wire(&sample(1))]),
        ),
        (
            "frame",
            "gen-stream-extremes",
            stream(&[wire(&sample(0)), wire(&weird)]),
        ),
        (
            "frame",
            "gen-wire-bitflip",
            structured(&sample(0), 2, &[[0, 7, 3]]),
        ),
        (
            "frame",
            "gen-wire-drop-insert",
            structured(&sample(300), 2, &[[2, 4, 0], [3, 9, 0x55]]),
        ),
        (
            "frame",
            "gen-payload-bitflip",
            structured(&sample(0), 3, &[[0, 3, 6]]),
        ),
        (
            "frame",
            "gen-payload-insert",
            structured(&sample(0), 3, &[[3, 1, 0x80]]),
        ),
    ]
}

fn settings_seeds() -> Vec<Seed> {
    let raw = |s: &Settings| {
        let mut v = vec![0u8];
        v.extend_from_slice(&s.to_image());
        v
    };
    let default = Settings::default();
    let mut bad_crc = raw(&default);
    bad_crc[1 + 100] ^= 0x01;
    let mut short = raw(&default);
    short.truncate(1 + IMAGE_LEN / 2);
    let mut longer = raw(&Settings::preset(Preset::Fast, ControllerKind::FuzzyPid));
    longer.extend_from_slice(&[0xff; 8]);
    vec![
        ("settings_image", "gen-raw-default", raw(&default)),
        (
            "settings_image",
            "gen-raw-fast-pid",
            raw(&Settings::preset(Preset::Fast, ControllerKind::Pid)),
        ),
        ("settings_image", "gen-raw-longer", longer),
        ("settings_image", "gen-raw-bad-crc", bad_crc),
        ("settings_image", "gen-raw-short", short),
        (
            "settings_image",
            "gen-mutated-probes",
            // Base 0 (paper, MPC-ESO), re-sealed; probing values into
            // eso.beta1, td.h0_s, cal.encoder.gain and hil.timeout_ms.
            vec![
                1, 0, 1, 2, 8, 0, 1, 2, 17, 0, 0x0e, 2, 43, 0, 0x03, 2, 56, 0, 0x14,
            ],
        ),
        (
            "settings_image",
            "gen-mutated-header",
            // Base 2 (paper, MPC), re-sealed; a padding byte and the kind.
            vec![1, 2, 1, 1, 13, 0, 1, 1, 12, 0, 3],
        ),
    ]
}

/// Every generated seed.
pub fn binary_seeds() -> Vec<Seed> {
    let mut v = console_seeds();
    v.extend(frame_seeds());
    v.extend(settings_seeds());
    v
}

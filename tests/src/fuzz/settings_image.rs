//! The stored settings image: [`Settings::from_image`] on arbitrary bytes and
//! on real images with corruptions.
//!
//! Input: the first byte selects the mode. Even: the rest is the image as
//! read from flash. Odd: a structured case ([`mutated`]).
//!
//! Invariants:
//! * no panic; an input shorter than [`IMAGE_LEN`] is a format error;
//! * an accepted image has every value inside its declared range, validates,
//!   and is canonical: [`Settings::to_image`] of the result gives back exactly
//!   the first [`IMAGE_LEN`] input bytes (bytes past them are not read).

use dca_app::settings::{Settings, SettingsError, IMAGE_LEN, PARAMS};
use dca_core::controller::{ControllerKind, Preset};

use super::{crc32_iso_hdlc, Bytes};

/// Offset of the first value in the image (after the header).
const VALUES_AT: usize = 16;

/// Read `img` and check the result.
fn check(img: &[u8]) {
    let r = Settings::from_image(img);
    if img.len() < IMAGE_LEN {
        assert_eq!(r.err(), Some(SettingsError::Format), "a short image");
        return;
    }
    let Ok((s, _)) = r else { return };
    for p in &PARAMS {
        let v = p.get(&s);
        let (lo, hi) = (p.min, p.max);
        assert!(
            v >= lo && v <= hi,
            "accepted image: {} = {v:e} is outside [{lo:e}, {hi:e}]",
            p.name
        );
    }
    if let Err(e) = s.validate() {
        panic!("accepted image does not validate: {e:?}");
    }
    let again = s.to_image();
    if again[..] != img[..IMAGE_LEN] {
        let at = (0..IMAGE_LEN).find(|&i| again[i] != img[i]).unwrap_or(0);
        let what = match at.checked_sub(VALUES_AT).map(|k| k / 8) {
            Some(k) if k < PARAMS.len() => PARAMS[k].name,
            Some(_) => "checksum",
            None => "header",
        };
        panic!(
            "accepted image is not canonical: byte {at} ({what}) is {:#04x}, to_image writes {:#04x}",
            img[at], again[at]
        );
    }
}

/// Values that probe the range checks of parameter `p`.
fn probe(b: &mut Bytes<'_>, k: usize) -> f64 {
    let p = &PARAMS[k % PARAMS.len()];
    let (lo, hi) = (p.min, p.max);
    let pick = b.u8();
    let edge = match pick % 4 {
        0 => lo,
        1 => hi,
        2 => (lo as f32) as f64,
        _ => (hi as f32) as f64,
    };
    match pick / 4 % 16 {
        0 => edge,
        1 => edge.next_up(),
        2 => edge.next_down(),
        3 => ((edge as f32).next_up()) as f64,
        4 => ((edge as f32).next_down()) as f64,
        5 => -0.0,
        6 => f64::NAN,
        7 => f64::INFINITY,
        8 => f64::NEG_INFINITY,
        9 => f64::from_bits(0x7ff8_0000_0000_0001),
        10 => 0.5 * (lo + hi),
        11 => f64::MIN_POSITIVE / 2.0,
        12 => lo + (hi - lo) * (b.u8() as f64 / 255.0),
        _ => f64::from_bits(b.u64()),
    }
}

/// A valid image, changed as the input says.
///
/// Input: a base byte (preset and controller kind of the starting image), a
/// mode byte (bit 0: re-seal the checksum after the changes, so that they
/// reach the checks behind it), then changes of 4 bytes each (at most 16):
/// `kind`, then operands. Kinds: xor a byte, set a byte, write a probing
/// value into a parameter slot (`probe`), write 8 raw bytes into a slot,
/// shorten the image, lengthen it.
pub fn mutated(data: &[u8]) {
    let mut b = Bytes::new(data);
    let base = b.u8();
    let preset = Preset::ALL[(base & 1) as usize];
    let kind = ControllerKind::ALL[(base >> 1) as usize % ControllerKind::ALL.len()];
    let mut img = Settings::preset(preset, kind).to_image().to_vec();
    let mode = b.u8();
    for _ in 0..16 {
        if b.is_empty() {
            break;
        }
        let op = b.u8();
        let pos = b.u16() as usize;
        let n = img.len();
        match op % 6 {
            0 if n > 0 => img[pos % n] ^= b.u8(),
            1 if n > 0 => img[pos % n] = b.u8(),
            2 => {
                let k = pos % PARAMS.len();
                let v = probe(&mut b, k);
                let at = VALUES_AT + 8 * k;
                if at + 8 <= n {
                    img[at..at + 8].copy_from_slice(&v.to_le_bytes());
                }
            }
            3 => {
                let at = VALUES_AT + 8 * (pos % PARAMS.len());
                let v = b.u64();
                if at + 8 <= n {
                    img[at..at + 8].copy_from_slice(&v.to_le_bytes());
                }
            }
            4 => img.truncate(pos % (n + 1)),
            _ => img.push(b.u8()),
        }
    }
    if mode & 1 != 0 && img.len() >= IMAGE_LEN {
        let crc = crc32_iso_hdlc(&img[..IMAGE_LEN - 4]);
        img[IMAGE_LEN - 4..IMAGE_LEN].copy_from_slice(&crc.to_le_bytes());
    }
    check(&img);
}

/// The settings-image harness; see the module documentation.
pub fn settings_image(data: &[u8]) {
    match data.split_first() {
        Some((mode, rest)) if mode & 1 == 1 => mutated(rest),
        Some((_, rest)) => check(rest),
        None => check(data),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_checksum_helper_seals_real_images() {
        let img = Settings::default().to_image();
        let crc = crc32_iso_hdlc(&img[..IMAGE_LEN - 4]);
        assert_eq!(img[IMAGE_LEN - 4..], crc.to_le_bytes());
    }
}

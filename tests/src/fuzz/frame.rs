//! HIL frames: the firmware's receive path ([`FrameReader`], [`decode`],
//! [`LinkMonitor`]) on arbitrary byte streams, and on real frames with
//! corruptions.
//!
//! Input: the first byte selects the mode. Even: the rest is the received
//! byte stream. Odd: a structured case ([`corrupted`]): a sample frame built
//! from the input, corrupted as the input says, then received.
//!
//! Invariants, for every frame received:
//! * the reader splits the stream exactly at the delimiters and reports an
//!   over-long frame as such;
//! * a frame the decoder accepts is a real frame: `encode` of the decoded
//!   message gives back exactly the received bytes and the delimiter;
//! * the monitor agrees with the decoder and with its documented start-up
//!   and sequence rules (skip until a valid `seq` 0, then consecutive `seq`s;
//!   same error, same message), and its counters add up: good + corrupt +
//!   lost + skipped = frames seen, late = 0.
//!
//! The defect this harness found first: postcard accepts an over-long varint
//! for `seq`, so a frame with a valid CRC whose `seq` was padded with
//! continuation bytes was accepted although `encode` never writes it; `decode`
//! now refuses any payload that is not the canonical encoding of its message
//! (regression `noncanonical-varint`).
//!
//! The message type is in one place (`Msg`, `sample_from`) and the
//! monitor's rules in one (`Expect`), so that a change of the frame API
//! changes only those.

use dca_app::frame::{
    decode, encode, FrameError, FrameReader, LinkError, LinkMonitor, ReadEvent, SampleFrame,
    MAX_FRAME_LEN,
};

use super::{crc16_ibm_3740, Bytes};

/// The host-to-firmware message the firmware decodes.
type Msg = SampleFrame;

/// A message from 28 input bytes (seq, then the six `f32` as raw bits).
fn sample_from(b: &mut Bytes<'_>) -> Msg {
    SampleFrame {
        seq: b.u32(),
        ref_m: f32::from_bits(b.u32()),
        xo_m: f32::from_bits(b.u32()),
        xi_m: f32::from_bits(b.u32()),
        p1_pa: f32::from_bits(b.u32()),
        p2_pa: f32::from_bits(b.u32()),
        ft_n: f32::from_bits(b.u32()),
    }
}

/// The message's fields as bits (NaN payloads included).
fn bits(m: &Msg) -> [u32; 7] {
    [
        m.seq,
        m.ref_m.to_bits(),
        m.xo_m.to_bits(),
        m.xi_m.to_bits(),
        m.p1_pa.to_bits(),
        m.p2_pa.to_bits(),
        m.ft_n.to_bits(),
    ]
}

/// The complete frame of `m`, delimiter included.
fn wire(m: &Msg) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME_LEN];
    let n = encode(m, &mut out).expect("a sample frame always fits");
    out[..n].to_vec()
}

/// COBS decoding of a frame body without its delimiter (None when invalid).
fn cobs_decode(body: &[u8]) -> Option<Vec<u8>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < body.len() {
        let code = body[i] as usize;
        if code == 0 || i + code > body.len() {
            return None;
        }
        out.extend_from_slice(&body[i + 1..i + code]);
        i += code;
        if code != 0xff && i < body.len() {
            out.push(0);
        }
    }
    Some(out)
}

/// COBS encoding (no delimiter).
fn cobs_encode(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8];
    let mut code_at = 0;
    for &b in data {
        if b == 0 {
            out[code_at] = (out.len() - code_at) as u8;
            code_at = out.len();
            out.push(0);
        } else {
            out.push(b);
            if out.len() - code_at == 0xff {
                out[code_at] = 0xff;
                code_at = out.len();
                out.push(0);
            }
        }
    }
    out[code_at] = (out.len() - code_at) as u8;
    out
}

/// An accepted frame that does not re-encode to itself: a defect.
fn not_canonical(body: &[u8], m: &Msg, again: &[u8]) {
    panic!(
        "an accepted frame is not what encode writes for its message {:?}:\n received {body:02x?}\n encode   {again:02x?}",
        bits(m)
    );
}

/// What the link monitor should do with a frame, from its documentation:
/// waiting until a valid frame with `seq` 0 makes the link live, then
/// expecting consecutive `seq`s. `None` for a decoding error.
#[derive(Debug, Default)]
struct Expect {
    live: bool,
    expected: u32,
    good: u32,
    skipped: u32,
    seen: u32,
}

impl Expect {
    /// The monitor's answer to a frame that decodes to `m` (or does not).
    fn frame(&mut self, m: &Result<Msg, FrameError>) -> Result<Option<[u32; 7]>, LinkError> {
        self.seen += 1;
        match m {
            Ok(m) if !self.live && m.seq == 0 => {
                (self.live, self.expected, self.good) = (true, 1, self.good + 1);
                Ok(Some(bits(m)))
            }
            _ if !self.live => {
                self.skipped += 1;
                Ok(None)
            }
            Err(e) => Err(LinkError::Corrupt(*e)),
            Ok(m) if m.seq != self.expected => Err(LinkError::Lost {
                expected: self.expected,
                got: m.seq,
            }),
            Ok(m) => {
                self.expected = self.expected.wrapping_add(1);
                self.good += 1;
                Ok(Some(bits(m)))
            }
        }
    }

    /// The monitor's answer to an over-long frame.
    fn overflow(&mut self) -> Option<LinkError> {
        self.seen += 1;
        if self.live {
            Some(LinkError::Corrupt(FrameError::Length))
        } else {
            self.skipped += 1;
            None
        }
    }
}

/// Receive `stream` as the firmware does and check every frame.
fn receive(stream: &[u8]) {
    let mut reader = FrameReader::new();
    let mut monitor = LinkMonitor::new();
    let mut want = Expect::default();
    // The reference split: the bytes since the last delimiter.
    let mut pending: Vec<u8> = Vec::new();
    for &byte in stream {
        let event = reader.push(byte);
        if byte != 0 {
            pending.push(byte);
            assert!(event.is_none(), "an event without a delimiter");
            continue;
        }
        let chunk = std::mem::take(&mut pending);
        match event {
            None => assert!(
                chunk.is_empty(),
                "a frame of {} bytes was lost",
                chunk.len()
            ),
            Some(ReadEvent::Overflow) => {
                assert!(
                    chunk.len() > MAX_FRAME_LEN,
                    "overflow at {} bytes",
                    chunk.len()
                );
                assert_eq!(monitor.overflow(), want.overflow());
            }
            Some(ReadEvent::Frame(body)) => {
                assert_eq!(&body[..], &chunk[..], "the reader split the stream wrongly");
                let (mut a, mut b) = (chunk.clone(), chunk.clone());
                let decoded = decode::<Msg>(&mut a);
                let got = monitor.receive(&mut b).map(|m| m.as_ref().map(bits));
                assert_eq!(got, want.frame(&decoded), "monitor vs. decoder {decoded:?}");
                if let Ok(m) = &decoded {
                    let again = wire(m);
                    let mut received = chunk.clone();
                    received.push(0);
                    if again != received {
                        not_canonical(&chunk, m, &again);
                    }
                }
            }
        }
        let c = monitor.counters();
        assert_eq!((c.good, c.skipped, c.late), (want.good, want.skipped, 0));
        assert_eq!(c.good + c.corrupt + c.lost + c.skipped, want.seen, "{c:?}");
        assert_eq!(monitor.is_live(), want.live);
        if want.live {
            assert_eq!(monitor.expected(), want.expected);
        }
    }
}

/// A real frame, corrupted as the input says, among valid neighbours.
///
/// Input: 28 bytes of message, a mode byte, then corruptions of 3 bytes each
/// (`kind`, `position`, `value`; at most 8). Mode bit 0: corrupt the postcard
/// payload and re-seal the CRC (a corruption the CRC does not catch, which
/// the payload decoder then meets), else corrupt the bytes on the wire. Bit 1:
/// send a valid frame with `seq` 0 before the corrupted one.
pub fn corrupted(data: &[u8]) {
    let mut b = Bytes::new(data);
    let msg = sample_from(&mut b);
    let mode = b.u8();
    let frame = wire(&msg);
    let payload_level = mode & 1 != 0;
    let mut bytes = if payload_level {
        let p = cobs_decode(&frame[..frame.len() - 1]).expect("encode writes valid COBS");
        p[..p.len() - 2].to_vec()
    } else {
        frame
    };
    for _ in 0..8 {
        if b.is_empty() {
            break;
        }
        let (kind, pos, value) = (b.u8(), b.u8() as usize, b.u8());
        let n = bytes.len();
        match kind % 5 {
            0 if n > 0 => bytes[pos % n] ^= 1 << (value % 8),
            1 if n > 0 => bytes[pos % n] = value,
            2 if n > 0 => {
                bytes.remove(pos % n);
            }
            3 => bytes.insert(pos % (n + 1), value),
            _ => bytes.truncate(pos % (n + 1)),
        }
    }
    if payload_level {
        let crc = crc16_ibm_3740(&bytes);
        bytes.extend_from_slice(&crc.to_le_bytes());
        bytes = cobs_encode(&bytes);
        bytes.push(0);
    }
    let mut stream = Vec::new();
    if mode & 2 != 0 {
        stream.extend(wire(&Msg::default()));
    }
    stream.extend(bytes);
    receive(&stream);
}

/// The frame harness; see the module documentation.
pub fn frame(data: &[u8]) {
    match data.split_first() {
        Some((mode, rest)) if mode & 1 == 1 => corrupted(rest),
        Some((_, rest)) => receive(rest),
        None => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helpers_agree_with_the_core() {
        let m = SampleFrame {
            seq: 300,
            ref_m: 0.05,
            ..SampleFrame::default()
        };
        let w = wire(&m);
        let p = cobs_decode(&w[..w.len() - 1]).unwrap();
        let (payload, crc) = p.split_at(p.len() - 2);
        assert_eq!(crc, crc16_ibm_3740(payload).to_le_bytes());
        assert_eq!(cobs_encode(&p), w[..w.len() - 1]);
        // seq 300 written as an over-long varint, CRC re-sealed: refused.
        let mut long = vec![0xac, 0x82, 0x80, 0x00];
        long.extend_from_slice(&payload[2..]);
        long.extend_from_slice(&crc16_ibm_3740(&long).to_le_bytes());
        let mut body = cobs_encode(&long);
        assert_eq!(decode::<Msg>(&mut body), Err(FrameError::Payload));
    }
}

//! HIL frames (dca_app::frame): round trips, corruption, sequence and timeout.

use dca_app::frame::{
    decode, encode, CommandFrame, FrameError, FrameReader, LinkError, LinkMonitor, ReadEvent,
    SampleFrame, MAX_FRAME_LEN,
};

fn sample(seq: u32) -> SampleFrame {
    SampleFrame {
        seq,
        ref_m: 0.05,
        xo_m: 0.012_345_678,
        xi_m: -1.0e-9,
        p1_pa: 640_127.4,
        p2_pa: 1.0e6,
        ft_n: -0.0,
    }
}

/// Encode and split into the body (without the delimiter).
fn wire(f: &SampleFrame) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME_LEN];
    let n = encode(f, &mut out).unwrap();
    assert_eq!(out[n - 1], 0, "delimiter");
    assert!(!out[..n - 1].contains(&0), "COBS removes every zero");
    out[..n - 1].to_vec()
}

#[test]
fn frames_round_trip_bit_for_bit() {
    let weird = SampleFrame {
        seq: u32::MAX,
        ref_m: f32::from_bits(0x7fc0_1234),
        xo_m: f32::MIN_POSITIVE / 2.0,
        xi_m: f32::INFINITY,
        p1_pa: f32::MAX,
        p2_pa: -0.0,
        ft_n: 1.0e-38,
    };
    for f in [sample(0), sample(12345), weird] {
        let mut body = wire(&f);
        let back: SampleFrame = decode(&mut body).unwrap();
        assert_eq!(back.seq, f.seq);
        let bits =
            |s: &SampleFrame| [s.ref_m, s.xo_m, s.xi_m, s.p1_pa, s.p2_pa, s.ft_n].map(f32::to_bits);
        assert_eq!(bits(&back), bits(&f));
    }
    let c = CommandFrame {
        seq: 7,
        v_cmd_mps: -0.0123,
        state: 2,
        faults: 0x41,
        flags: 8,
    };
    let mut out = [0u8; MAX_FRAME_LEN];
    let n = encode(&c, &mut out).unwrap();
    let back: CommandFrame = decode(&mut out[..n - 1]).unwrap();
    assert_eq!(back, c);
}

/// The firmware writes the reply frame inside the control tick's deadline
/// (firmware/src/main.rs, docs/firmware.md): 18 bytes at the most. postcard
/// writes `seq` (u32) in at most 5 bytes and `faults` (u16) in at most 3,
/// the command in 4, state and flags in 1 each; the CRC adds 2, COBS 1 and
/// the delimiter 1.
#[test]
fn a_command_frame_is_at_most_18_bytes() {
    let mut longest = 0;
    for seq in [0, 127, 128, 1 << 21, u32::MAX] {
        for faults in [0, 0x7f, 0x80, 1 << 14, u16::MAX] {
            for v_cmd_mps in [0.0, -0.1, f32::MAX, f32::NAN] {
                let c = CommandFrame {
                    seq,
                    v_cmd_mps,
                    state: u8::MAX,
                    faults,
                    flags: u8::MAX,
                };
                let mut out = [0u8; MAX_FRAME_LEN];
                longest = longest.max(encode(&c, &mut out).unwrap());
            }
        }
    }
    assert_eq!(longest, 18);
}

#[test]
fn every_single_bit_flip_is_detected() {
    let good = wire(&sample(3));
    for i in 0..good.len() {
        for bit in 0..8 {
            let mut body = good.clone();
            body[i] ^= 1 << bit;
            if body[i] == 0 {
                // A zero would have split the frame at the receiver: a COBS or
                // length failure of the shorter frame, also refused.
                body.truncate(i);
            }
            let r: Result<SampleFrame, _> = decode(&mut body);
            assert!(r.is_err(), "flip byte {i} bit {bit} accepted");
        }
    }
}

#[test]
fn truncated_and_padded_frames_are_refused() {
    let good = wire(&sample(3));
    for n in 0..good.len() {
        let mut body = good[..n].to_vec();
        assert!(decode::<SampleFrame>(&mut body).is_err(), "prefix {n}");
    }
    // A valid command frame is not a sample frame.
    let mut out = [0u8; MAX_FRAME_LEN];
    let n = encode(&CommandFrame::default(), &mut out).unwrap();
    assert!(decode::<SampleFrame>(&mut out[..n - 1]).is_err());
    let mut long = vec![1u8; MAX_FRAME_LEN + 1];
    assert_eq!(decode::<SampleFrame>(&mut long), Err(FrameError::Length));
    // A body with a delimiter inside is not one frame, even if its start is.
    let mut two = wire(&sample(3));
    two.push(0);
    two.extend([7, 7, 7]);
    assert_eq!(decode::<SampleFrame>(&mut two), Err(FrameError::Cobs));
}

#[test]
fn reader_splits_a_stream_and_resynchronises_after_garbage() {
    let mut stream = vec![0x55, 0x66]; // a torn frame before the first delimiter
    stream.push(0);
    for k in 0..3 {
        stream.extend(wire(&sample(k)));
        stream.push(0);
    }
    stream.extend(vec![9u8; MAX_FRAME_LEN + 5]);
    stream.push(0);
    stream.push(0);
    let mut r = FrameReader::new();
    let mut mon = LinkMonitor::new();
    let mut got = Vec::new();
    for b in stream {
        match r.push(b) {
            Some(ReadEvent::Frame(body)) => got.push(mon.receive(body)),
            Some(ReadEvent::Overflow) => got.push(mon.overflow().map_or(Ok(None), Err)),
            None => {}
        }
    }
    // The torn frame comes before the link is live: skipped, no error.
    assert_eq!(got[0], Ok(None));
    assert_eq!(got[1].unwrap().unwrap().seq, 0);
    assert_eq!(got[2].unwrap().unwrap().seq, 1);
    assert_eq!(got[3].unwrap().unwrap().seq, 2);
    // Once live, an over-long frame is an error.
    assert_eq!(got[4], Err(LinkError::Corrupt(FrameError::Length)));
    assert_eq!(got.len(), 5);
    let c = mon.counters();
    assert_eq!(
        (c.good, c.corrupt, c.lost, c.late, c.skipped),
        (3, 1, 0, 0, 1)
    );
}

#[test]
fn a_waiting_link_skips_noise_and_stale_frames_and_never_times_out() {
    let mut mon = LinkMonitor::new();
    assert!(!mon.is_live());
    // However long the host takes to open its port: no timeout.
    for _ in 0..10_000 {
        assert_eq!(mon.tick(100), None);
    }
    // A banner, line noise, an over-long burst, a stale frame of an old run.
    let mut r = FrameReader::new();
    let mut events = 0;
    let mut noise = b"dca-firmware ready\r\n".to_vec();
    noise.push(0);
    noise.extend([0xff; 3 * MAX_FRAME_LEN]);
    noise.push(0);
    noise.extend(wire(&sample(41)));
    noise.push(0);
    for b in noise {
        match r.push(b) {
            Some(ReadEvent::Frame(body)) => {
                events += 1;
                assert_eq!(mon.receive(body), Ok(None));
            }
            Some(ReadEvent::Overflow) => {
                events += 1;
                assert_eq!(mon.overflow(), None);
            }
            None => {}
        }
    }
    assert_eq!(events, 3);
    assert!(!mon.is_live());
    assert_eq!(mon.counters().skipped, 3);
    assert_eq!(mon.counters().good, 0);
    // The first valid frame with seq 0 starts supervision.
    assert_eq!(mon.receive(&mut wire(&sample(0))).unwrap().unwrap().seq, 0);
    assert!(mon.is_live());
    for _ in 0..99 {
        assert_eq!(mon.tick(100), None);
    }
    assert_eq!(mon.tick(100), Some(LinkError::Late));
    // Noise is an error now.
    assert!(matches!(
        mon.receive(&mut b"junk".to_vec()),
        Err(LinkError::Corrupt(_))
    ));
    assert!(mon.overflow().is_some());
    // After a restart (a fault cleared, arming again) it waits again.
    mon.restart();
    assert!(!mon.is_live());
    assert_eq!(mon.receive(&mut wire(&sample(5))), Ok(None));
    assert_eq!(mon.tick(1), None);
}

#[test]
fn monitor_counts_gaps_repeats_and_timeouts() {
    let mut mon = LinkMonitor::new();
    assert_eq!(mon.receive(&mut wire(&sample(0))).unwrap().unwrap().seq, 0);
    assert_eq!(
        mon.receive(&mut wire(&sample(2))),
        Err(LinkError::Lost {
            expected: 1,
            got: 2
        })
    );
    // A repeat of an old frame is not accepted either.
    assert!(mon.receive(&mut wire(&sample(0))).is_err());
    assert_eq!(mon.expected(), 1);
    mon.restart();
    assert_eq!(mon.receive(&mut wire(&sample(0))).unwrap().unwrap().seq, 0);
    // Timeout: fires once at the limit, restarts with a frame; 0 disables.
    for _ in 0..4 {
        assert_eq!(mon.tick(5), None);
    }
    assert_eq!(mon.tick(5), Some(LinkError::Late));
    assert_eq!(mon.tick(5), None);
    assert_eq!(mon.receive(&mut wire(&sample(1))).unwrap().unwrap().seq, 1);
    for _ in 0..4 {
        assert_eq!(mon.tick(5), None);
    }
    for _ in 0..100 {
        assert_eq!(mon.tick(0), None);
    }
    let c = mon.counters();
    assert_eq!((c.good, c.lost, c.late), (3, 2, 1));
}

//! The on-board record's packing and frames (dca_app::record).

use dca_app::frame::{self, MAX_FRAME_LEN};
use dca_app::record::{
    fields, Packer, RecordChunk, RecordHead, RecordState, Recorder, ADC_MAX, CHUNK_ROWS, REF_LSB_M,
    ROW_BYTES, VCMD_LSB_MPS,
};
use dca_app::settings::Calibration;
use dca_app::supervisor::Faults;
use dca_core::controller::Sample;
use proptest::prelude::*;

fn cal() -> Calibration {
    Calibration::nominal()
}

#[test]
fn every_fault_bit_fits_the_rows_byte() {
    let all = Faults::NAMES.iter().fold(0u16, |a, (b, _)| a | b);
    assert!(all <= 0xff, "{all:#x}");
    let row = Packer::new(&cal()).pack(0.0, 0.0, &Sample::default(), all);
    assert_eq!(u16::from(fields(&row).faults), all);
}

#[test]
fn a_board_reading_comes_back_bit_for_bit() {
    // What the board computes from codes (offset + gain * code, f32) is
    // recorded as that code and read back as the same f32.
    let c = cal();
    let p = Packer::new(&c);
    let head = RecordHead::new(1, 4, &c);
    for code in [0u16, 1, 2047, 2048, 4094, 4095] {
        for count in [-8_388_608i32, -1, 0, 1, 250_000, 8_388_607] {
            let s = Sample {
                xo_m: c.lvdt.apply(f32::from(code)),
                p1_pa: c.p1.apply(f32::from(code)),
                p2_pa: c.p2.apply(f32::from(4095 - code)),
                ft_n: c.force.apply(f32::from(code)),
                xi_m: c.encoder.apply(count as f32),
            };
            let row = p.pack(0.0, 0.0, &s, 0);
            let f = fields(&row);
            assert_eq!(f.adc, [code, code, 4095 - code, code]);
            assert_eq!(f.xi_count, count);
            let back = head.row(&row).sample;
            assert_eq!(back, s, "code {code}, count {count}");
        }
    }
}

#[test]
fn values_beyond_a_channel_clamp_and_non_finite_ones_are_zero() {
    let c = cal();
    let p = Packer::new(&c);
    let s = Sample {
        xo_m: 1.0,
        p1_pa: -1.0e7,
        p2_pa: f32::NAN,
        ft_n: f32::INFINITY,
        xi_m: -10.0,
    };
    let f = fields(&p.pack(5.0, f32::NAN, &s, 0));
    assert_eq!(f.adc, [ADC_MAX as u16, 0, 0, ADC_MAX as u16]);
    assert_eq!(f.xi_count, -(1 << 23));
    assert_eq!(f.ref_q23, (1 << 23) - 1);
    assert_eq!(f.vcmd_q23, 0);
}

#[test]
fn frames_fit_the_link_frame_and_decode() {
    let head = RecordHead::new(u32::MAX, 4, &cal());
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = frame::encode(&head, &mut buf).unwrap();
    let back: RecordHead = frame::decode(&mut buf[..n - 1]).unwrap();
    assert_eq!(back, head);
    let chunk = RecordChunk {
        seq: u32::MAX,
        rows: [[0xff; ROW_BYTES]; CHUNK_ROWS],
    };
    let n = frame::encode(&chunk, &mut buf).unwrap();
    let back: RecordChunk = frame::decode(&mut buf[..n - 1]).unwrap();
    assert_eq!(back, chunk);
}

#[test]
fn the_recorder_fills_both_blocks_in_order_and_stops_when_full() {
    let (mut a, mut b) = ([[0u8; ROW_BYTES]; 3], [[0u8; ROW_BYTES]; 4]);
    let mut r = Recorder::new(&mut a, &mut b);
    assert_eq!(r.capacity(), 7);
    assert!(r.arm(8, &cal(), 0).is_err());
    r.arm(6, &cal(), 0).unwrap();
    let s = Sample::default();
    r.push(false, 0.0, 0.0, &s, 0);
    assert_eq!((r.info().state, r.info().rows), (RecordState::Armed, 0));
    for k in 0..9 {
        // Once started, every tick counts, running or not.
        r.push(k < 2, k as f32 * 1e-3, 0.0, &s, 0);
    }
    let i = r.info();
    assert_eq!((i.state, i.rows, i.head.rows), (RecordState::Done, 6, 6));
    let mut out = [[0u8; ROW_BYTES]; 8];
    assert_eq!(r.rows(0, &mut out), 6);
    let head = i.head;
    for (k, row) in out[..6].iter().enumerate() {
        assert!((head.row(row).ref_m - k as f64 * 1e-3).abs() <= REF_LSB_M / 2.0);
    }
    assert_eq!(r.rows(4, &mut out), 2);
}

proptest! {
    #[test]
    fn reference_and_command_within_half_their_resolution(
        r in -0.999f32..0.999, v in -0.999f32..0.999, faults in 0u16..256,
    ) {
        let row = Packer::new(&cal()).pack(r, v, &Sample::default(), faults);
        let back = RecordHead::new(1, 0, &cal()).row(&row);
        prop_assert!((back.ref_m - f64::from(r)).abs() <= REF_LSB_M / 2.0);
        prop_assert!((back.v_cmd_mps - f64::from(v)).abs() <= VCMD_LSB_MPS / 2.0);
        prop_assert_eq!(back.faults, faults);
    }

    #[test]
    fn any_sample_within_half_a_code(
        xo in -0.01f32..0.11, p1 in 0.0f32..1.0e7, p2 in 0.0f32..1.0e7,
        ft in -2000.0f32..2000.0, xi in -1.0f32..1.0,
    ) {
        let c = cal();
        let s = Sample { xo_m: xo, p1_pa: p1, p2_pa: p2, ft_n: ft, xi_m: xi };
        let row = Packer::new(&c).pack(0.0, 0.0, &s, 0);
        let b = RecordHead::new(1, 0, &c).row(&row).sample;
        for (got, want, ch) in [
            (b.xo_m, xo, c.lvdt), (b.p1_pa, p1, c.p1), (b.p2_pa, p2, c.p2),
            (b.ft_n, ft, c.force), (b.xi_m, xi, c.encoder),
        ] {
            // Half a code, and the f32 rounding of the value itself.
            let tol = 0.5 * ch.gain + 4.0 * f32::EPSILON * want.abs().max(ch.offset.abs());
            prop_assert!((got - want).abs() <= tol, "{} for {} (code {})", got, want, ch.gain);
        }
    }
}

//! Settings (dca_app::settings): paths, ranges, validation and the image.

use dca_app::settings::{find, Settings, SettingsError, IMAGE_LEN, PARAMS};
use dca_core::controller::{ControllerKind, Preset};

#[test]
fn defaults_are_the_paper_mpc_eso_at_the_board_tick() {
    let s = Settings::default();
    assert_eq!(s.controller.kind, ControllerKind::MpcEso);
    assert_eq!(s.controller.base_dt_s, 1e-3);
    assert_eq!(s.get("mpc_eso.np"), Ok(8.0));
    assert_eq!(s.get("eso.h_s"), Ok(0.006));
    assert_eq!(s.get("mpc.rw"), Ok(33.0));
    let c = s.validate().unwrap();
    assert_eq!(c.periods(), (6, 100));
    // The LVDT calibration of docs/model.md section 5: code 0 reads lo + LSB/2.
    let lsb = 0.120 / 4096.0;
    assert!((s.cal.lvdt.apply(0.0) as f64 - (-0.010 + lsb / 2.0)).abs() < 1e-9);
}

#[test]
fn names_are_unique_and_every_default_is_in_range() {
    let s = Settings::default();
    for (i, p) in PARAMS.iter().enumerate() {
        assert!(
            PARAMS[..i].iter().all(|q| q.name != p.name),
            "{} twice",
            p.name
        );
        let v = p.get(&s);
        assert!(
            v >= p.min && v <= p.max,
            "{} = {v} outside [{}, {}]",
            p.name,
            p.min,
            p.max
        );
        assert!(find(p.name).is_some());
    }
}

#[test]
fn set_checks_range_type_and_the_whole_design_and_never_mutates() {
    let s = Settings::default();
    let (t, c) = s.with("mpc_eso.rw", 300.0).unwrap();
    assert_eq!(t.get("mpc_eso.rw"), Ok(300.0));
    assert_eq!(c.kind(), ControllerKind::MpcEso);
    assert_eq!(s.get("mpc_eso.rw"), Ok(33.0), "the original is unchanged");
    assert_eq!(s.with("nope", 1.0).unwrap_err(), SettingsError::UnknownName);
    assert_eq!(
        s.with("mpc_eso.rw", -1.0).unwrap_err(),
        SettingsError::Range
    );
    assert_eq!(
        s.with("mpc_eso.rw", f64::NAN).unwrap_err(),
        SettingsError::Range
    );
    assert_eq!(
        s.with("mpc_eso.np", 8.5).unwrap_err(),
        SettingsError::NotInteger
    );
    assert_eq!(
        s.with("drive.invert", 2.0).unwrap_err(),
        SettingsError::Range
    );
    // In range alone, but the design refuses it: Nc > Np of the plain MPC,
    // which is not the selected kind.
    assert!(matches!(
        s.with("mpc.np", 1.0),
        Err(SettingsError::Design(_))
    ));
    assert!(matches!(
        s.with("limits.x_min_m", 0.2),
        Err(SettingsError::Design(_))
    ));
    assert_eq!(
        s.with("sup.stroke_min_m", 0.2).unwrap_err(),
        SettingsError::Order
    );
    let (t, _) = s.with("drive.invert", 1.0).unwrap();
    assert!(t.drive.invert);
}

#[test]
fn image_round_trips_and_refuses_any_damage() {
    let (s, _) = Settings::default()
        .with_kind(ControllerKind::FuzzyPid)
        .with_preset(Preset::Fast)
        .with("cal.p1.offset", -1234.5)
        .unwrap();
    let img = s.to_image();
    assert_eq!(img.len(), IMAGE_LEN);
    assert_eq!(IMAGE_LEN % 4, 0);
    let (back, c) = Settings::from_image(&img).unwrap();
    assert_eq!(back, s);
    assert_eq!(c.kind(), ControllerKind::FuzzyPid);
    for i in 0..img.len() {
        let mut bad = img;
        bad[i] ^= 0x10;
        assert!(
            Settings::from_image(&bad).is_err(),
            "byte {i} flip accepted"
        );
    }
    assert_eq!(
        Settings::from_image(&img[..IMAGE_LEN - 1]).unwrap_err(),
        SettingsError::Format
    );
    assert_eq!(
        Settings::from_image(&[0xff; IMAGE_LEN]).unwrap_err(),
        SettingsError::Format
    );
}

#[test]
fn drive_scale_maps_speed_to_duty_and_direction() {
    let mut d = Settings::default().drive;
    assert_eq!(d.duty(0.05), (0.5, true));
    assert_eq!(d.duty(-0.2), (1.0, false));
    assert_eq!(d.duty(f32::NAN).0, 0.0);
    d.invert = true;
    assert_eq!(d.duty(0.05), (0.5, false));
}

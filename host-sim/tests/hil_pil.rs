//! Processor-in-the-loop: the paper's closed-loop scenarios through the emulated
//! firmware (QEMU netduinoplus2), bit-identical to the software loop.
//!
//! Needs `qemu-system-arm` and the `qemu` build of the firmware (`cargo fw-qemu`);
//! `.ci/firmware.sh` runs these with `--ignored`. The ELF is taken from
//! `DCA_QEMU_ELF`, by default `target/qemu/thumbv7em-none-eabihf/firmware/dca-firmware`.

use std::path::PathBuf;
use std::time::Duration;

use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use dca_core::frame::{self, CommandFrame, SampleFrame, MAX_FRAME_LEN};
use dca_core::supervisor::{Faults, State};
use host_sim::hil::{run_hil_qemu, run_software, Emulator, QemuOptions};
use host_sim::plant::Plant;
use host_sim::scenario::Scenario;
use host_sim::sensors::SensorMode;
use host_sim::sim::RunSpec;

fn elf() -> PathBuf {
    std::env::var_os("DCA_QEMU_ELF")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../target/qemu/thumbv7em-none-eabihf/firmware/dca-firmware")
        })
}

fn spec(name: &str, kind: ControllerKind) -> RunSpec {
    RunSpec {
        scenario: Scenario::by_name(name).unwrap(),
        controller: ControllerConfig::preset(Preset::Paper, kind),
        plant: Plant::nominal(),
        effects: Default::default(),
        sensors: SensorMode::Ideal,
        seed: 0,
        dt_s: 1e-4,
    }
}

#[test]
#[ignore = "needs qemu-system-arm and `cargo fw-qemu`; run by .ci/firmware.sh"]
fn paper_scenarios_through_the_emulated_firmware_are_bit_identical() {
    let opts = QemuOptions::default();
    for name in std::env::var("PIL_SCENARIOS")
        .unwrap_or("step,sine,stepload,sineload".into())
        .split(',')
    {
        let s = spec(name, ControllerKind::MpcEso);
        let t0 = std::time::Instant::now();
        let emulated = run_hil_qemu(&s, &elf(), &opts).unwrap_or_else(|e| panic!("{name}: {e}"));
        let soft = run_software(&s).unwrap();
        let n = emulated.rows.len();
        assert_eq!(n, soft.rows.len());
        assert_eq!(
            emulated.first_difference(&soft),
            None,
            "{name}: drive commands differ"
        );
        let moving = soft
            .rows
            .iter()
            .filter(|r| r.reply.v_cmd_mps != 0.0)
            .count();
        assert!(
            moving > 100,
            "{name}: the controller hardly moved ({moving} ticks)"
        );
        println!(
            "{name}: {n} ticks bit-identical ({moving} non-zero commands), {:.1} s",
            t0.elapsed().as_secs_f64()
        );
    }
}

/// Send one raw frame body (already encoded, delimiter included) and read the reply.
fn exchange(link: &mut std::net::TcpStream, bytes: &[u8]) -> CommandFrame {
    use std::io::{Read, Write};
    link.write_all(bytes).unwrap();
    let mut body = Vec::new();
    let mut b = [0u8; 1];
    loop {
        link.read_exact(&mut b).unwrap();
        if b[0] == 0 {
            if body.is_empty() {
                continue;
            }
            break;
        }
        body.push(b[0]);
    }
    frame::decode(&mut body).unwrap()
}

fn encoded(f: &SampleFrame) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME_LEN];
    let n = frame::encode(f, &mut out).unwrap();
    out[..n].to_vec()
}

fn at_rest(seq: u32) -> SampleFrame {
    SampleFrame {
        seq,
        ref_m: 0.05,
        xo_m: 0.0,
        xi_m: 0.0,
        p1_pa: 6.4e5,
        p2_pa: 1.0e6,
        ft_n: 0.0,
    }
}

#[test]
#[ignore = "needs qemu-system-arm and `cargo fw-qemu`; run by .ci/firmware.sh"]
fn link_and_sensor_faults_force_the_drive_to_zero() {
    let opts = QemuOptions {
        timeout: Duration::from_secs(10),
        ..QemuOptions::default()
    };
    let mut emu = Emulator::start(&elf(), &opts).unwrap();
    let mut link = emu.link.take().unwrap();
    link.set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    let fault = State::Fault as u8;
    // Each case: arm in HIL mode, one good frame (the drive moves), then the
    // bad one: the reply carries the fault and a zero command.
    let cases: Vec<(&str, Vec<u8>, u16)> = vec![
        ("lost frame", encoded(&at_rest(2)), Faults::HIL_LINK),
        (
            "corrupt frame",
            {
                let mut b = encoded(&at_rest(1));
                b[3] ^= 0x40;
                b
            },
            Faults::HIL_LINK,
        ),
        (
            "open LVDT",
            encoded(&SampleFrame {
                xo_m: -0.009_985,
                ..at_rest(1)
            }),
            Faults::SENSOR_RANGE,
        ),
        (
            "over-pressure",
            encoded(&SampleFrame {
                p1_pa: 9.5e6,
                ..at_rest(1)
            }),
            Faults::OVERPRESSURE,
        ),
        (
            "stroke",
            encoded(&SampleFrame {
                xi_m: 0.107,
                ..at_rest(1)
            }),
            Faults::STROKE,
        ),
        (
            "non-finite reference",
            encoded(&SampleFrame {
                ref_m: f32::NAN,
                ..at_rest(1)
            }),
            Faults::NON_FINITE,
        ),
    ];
    // The PI law commands on its first tick (MPC-ESO's TD delays the first move).
    emu.console.must("controller pid").unwrap();
    emu.console.must("hil on").unwrap();
    for (what, bad, bit) in cases {
        emu.console.must("arm").unwrap();
        let good = exchange(&mut link, &encoded(&at_rest(0)));
        assert_eq!(good.seq, 0, "{what}");
        assert_eq!(good.faults, 0, "{what}");
        assert_ne!(
            good.v_cmd_mps, 0.0,
            "{what}: the drive should move towards 50 mm"
        );
        let r = exchange(&mut link, &bad);
        assert_eq!(r.v_cmd_mps, 0.0, "{what}: drive not zeroed");
        assert_eq!(r.state, fault, "{what}");
        assert!(Faults(r.faults).has(bit), "{what}: faults {:#x}", r.faults);
        // Latched: the next good frame is answered with zero too.
        let r = exchange(&mut link, &encoded(&at_rest(r.seq.max(1) + 1)));
        assert_eq!(r.v_cmd_mps, 0.0, "{what}: fault not latched");
        let shown = emu.console.must("fault").unwrap();
        assert!(shown.starts_with("faults="), "{shown}");
        assert!(!shown.starts_with("faults=none"), "{what}: {shown}");
        assert!(
            emu.console.command("arm").unwrap().starts_with("error:"),
            "{what}: armed in fault"
        );
        emu.console.must("clear").unwrap();
    }
    let shown = emu.console.must("fault").unwrap();
    assert!(
        shown.contains("lost=") && !shown.contains("lost=0 "),
        "{shown}"
    );
    emu.console.must("hil off").unwrap();
    emu.quit().unwrap();
}

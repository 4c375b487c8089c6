//! The board-facing paths without a board or an emulator: a pseudo-terminal
//! pair stands for the USB-serial tty, and its far end is played by this test
//! (silent, or a software board built from dca-core's own HIL pieces that
//! sends noise before its first reply).

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use dca_app::frame::{self, CommandFrame, FrameReader, LinkMonitor, ReadEvent};
use dca_app::settings::{Settings, BOARD_DT_S};
use dca_app::supervisor::ControlLoop;
use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use host_sim::hil::board::console::{ConsoleClient, CONSOLE_BAUD};
use host_sim::hil::board::port::SerialLink;
use host_sim::hil::board::BoardError;
use host_sim::hil::{run_hil_serial, run_software, HilError, SerialOptions};
use host_sim::model::plant::Plant;
use host_sim::model::scenario::Scenario;
use host_sim::model::sensors::SensorMode;
use host_sim::sim::RunSpec;
use serialport::{SerialPort, TTYPort};

fn spec() -> RunSpec {
    RunSpec {
        scenario: Scenario::by_name("step").unwrap(),
        controller: ControllerConfig::preset(Preset::Paper, ControllerKind::Pid),
        plant: Plant::nominal(),
        effects: Default::default(),
        sensors: SensorMode::Realistic,
        seed: 4,
        dt_s: 1e-4,
    }
}

/// A pty pair: the far end (the "board") and the path the host opens.
fn pty() -> (TTYPort, TTYPort, String) {
    let (master, slave) = TTYPort::pair().expect("a pseudo-terminal pair");
    let path = slave.name().expect("the slave's path");
    (master, slave, path)
}

#[test]
fn a_console_that_does_not_answer_is_named_within_seconds() {
    let (_board, _keep, path) = pty();
    let t0 = Instant::now();
    let link = SerialLink::open(&path, CONSOLE_BAUD, Duration::from_millis(50)).unwrap();
    let e = ConsoleClient::connect(link, Duration::from_secs(2))
        .err()
        .expect("no console there");
    let secs = t0.elapsed().as_secs_f64();
    assert!(matches!(e, BoardError::NoConsole { .. }), "{e}");
    let text = e.to_string();
    assert!(
        text.contains(&path) && text.contains("115200") && text.contains("ping"),
        "{text}"
    );
    assert!(secs < 8.0, "took {secs} s");
}

#[test]
fn a_hil_port_that_does_not_answer_is_named_within_seconds() {
    let (_board, _keep, path) = pty();
    let t0 = Instant::now();
    let opts = SerialOptions {
        timeout: Duration::from_secs(1),
        ..SerialOptions::default()
    };
    let e = run_hil_serial(&spec(), &path, &opts).expect_err("no board there");
    let secs = t0.elapsed().as_secs_f64();
    assert!(matches!(e, HilError::NoLink { .. }), "{e}");
    let text = e.to_string();
    assert!(
        text.contains(&path) && text.contains("921600") && text.contains("hil on"),
        "{text}"
    );
    assert!(secs < 4.0, "took {secs} s");
}

/// A board in HIL mode, armed, as the firmware runs it (frame reader, link
/// monitor, control loop), on the far end of the pty. As soon as the host's
/// first bytes arrive, before its first reply, it sends what a real port may
/// carry: a banner, line noise, a stale reply.
fn software_board(mut port: TTYPort, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<u32> {
    std::thread::spawn(move || {
        let settings = Settings::preset(Preset::Paper, ControllerKind::Pid);
        let mut lp = ControlLoop::new(settings.validate().unwrap(), settings.limits, BOARD_DT_S);
        lp.arm().unwrap();
        let mut reader = FrameReader::new();
        let mut link = LinkMonitor::new();
        port.set_timeout(Duration::from_millis(20)).unwrap();
        let mut noise = b"dca-firmware 0.1.0 ready; type 'help'\r\n".to_vec();
        noise.extend([0x00, 0x13, 0x37, 0xff, 0x00]);
        let mut stale = [0u8; 64];
        let n = frame::encode(
            &CommandFrame {
                seq: 41,
                ..Default::default()
            },
            &mut stale,
        )
        .unwrap();
        noise.extend(&stale[..n]);
        let mut noise = Some(noise);
        let mut buf = [0u8; 256];
        let mut ticks = 0;
        while !stop.load(Ordering::Relaxed) {
            let n = match port.read(&mut buf) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
                Err(_) => break,
            };
            if let Some(junk) = noise.take() {
                port.write_all(&junk).unwrap();
            }
            for &b in &buf[..n] {
                let Some(ReadEvent::Frame(body)) = reader.push(b) else {
                    continue;
                };
                let Ok(Some(f)) = link.receive(body) else {
                    continue;
                };
                let o = lp.tick(&f.sample(), Some(f.ref_m));
                let reply = CommandFrame {
                    seq: f.seq,
                    v_cmd_mps: o.v_cmd_mps,
                    state: o.state,
                    faults: o.faults,
                    flags: o.flags.0,
                };
                let mut out = [0u8; 64];
                let m = frame::encode(&reply, &mut out).unwrap();
                port.write_all(&out[..m]).unwrap();
                ticks += 1;
            }
        }
        ticks
    })
}

#[test]
fn the_host_resynchronises_on_noise_and_matches_the_software_loop() {
    let (board, _keep, path) = pty();
    let stop = Arc::new(AtomicBool::new(false));
    let handle = software_board(board, Arc::clone(&stop));
    let s = spec();
    let trace = run_hil_serial(&s, &path, &SerialOptions::default()).unwrap();
    stop.store(true, Ordering::Relaxed);
    let ticks = handle.join().unwrap();
    let soft = run_software(&s).unwrap();
    assert_eq!(trace.rows.len(), 6000);
    assert_eq!(ticks, 6000);
    assert_eq!(trace.first_difference(&soft), None);
}

/// `hil --qemu` and `console --qemu` without QEMU on the path: the error comes
/// at once, before any firmware build (a build would need `cargo`, which is
/// not reachable here either), and says how to install QEMU.
#[test]
fn a_missing_qemu_is_said_before_any_build() {
    let empty = std::env::temp_dir().join(format!("dca-no-qemu-{}", std::process::id()));
    std::fs::create_dir_all(&empty).unwrap();
    for args in [
        &["hil", "--qemu", "--scenario", "step", "--controller", "pid"][..],
        &["console", "--qemu"][..],
    ] {
        let t0 = Instant::now();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(args)
            .env("PATH", &empty)
            .env("CARGO", empty.join("no-cargo"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}: {err}");
        assert!(
            err.contains("qemu-system-arm not found on PATH")
                && err.contains("apt-get install qemu-system-arm"),
            "{args:?}: {err}"
        );
        assert!(!err.contains("building"), "{args:?}: {err}");
        assert!(t0.elapsed() < Duration::from_secs(5), "{args:?}");
    }
    std::fs::remove_dir_all(&empty).unwrap();
}

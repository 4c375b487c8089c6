//! The console (dca_app::console) against a model of the board built from the
//! core's own control loop.

use dca_app::console::{
    write_log_header, write_log_row, Console, Edit, LineEditor, LineError, LogRow, Output,
    Received, Receiver, Status, Target, COMMANDS, MAX_LINE, RX_QUEUE_BYTES,
};
use dca_app::frame;
use dca_app::record::{
    PackedRow, RecordChunk, RecordError, RecordHead, RecordInfo, Recorder, CHUNK_ROWS, REF_LSB_M,
    VCMD_LSB_MPS,
};
use dca_app::settings::{Calibration, Settings};
use dca_app::supervisor::{ControlLoop, Refused, State};
use dca_app::text::Buf;
use dca_core::controller::{Controller, ControllerKind, Sample};
use proptest::prelude::*;

struct Model {
    lp: ControlLoop,
    settings: Settings,
    flash: Option<Vec<u8>>,
    telemetry: Option<u32>,
    hil: bool,
    echo: bool,
    applied: u32,
    rec: Recorder<'static>,
}

/// Rows of the model's record buffer: 7 in a first block, 5 in a second.
const REC_A: usize = 7;
const REC_B: usize = 5;

fn block(n: usize) -> &'static mut [PackedRow] {
    Box::leak(vec![[0u8; 16]; n].into_boxed_slice())
}

impl Model {
    fn new() -> Self {
        let s = Settings::default();
        let mut lp = ControlLoop::new(s.validate().unwrap(), s.limits, 1e-3);
        lp.tick(&Sample::default(), None);
        Self {
            lp,
            settings: s,
            flash: None,
            telemetry: None,
            hil: false,
            echo: false,
            applied: 0,
            rec: Recorder::new(block(REC_A), block(REC_B)),
        }
    }

    /// One control tick on `sample`, recorded as the firmware records it;
    /// the command.
    fn tick(&mut self, sample: &Sample) -> f32 {
        let out = self.lp.tick(sample, None);
        let running = self.lp.supervisor().state() == State::Running;
        self.rec.push(
            running,
            out.ref_m,
            out.v_cmd_mps,
            sample,
            self.lp.supervisor().faults().0,
        );
        out.v_cmd_mps
    }
}

impl Target for Model {
    fn status(&mut self) -> Status {
        Status {
            state: self.lp.supervisor().state() as u8,
            faults: self.lp.supervisor().faults().0,
            sample: *self.lp.last_sample(),
            ref_m: self.lp.reference_now(),
            ticks: self.lp.ticks(),
            hil: self.hil,
            telemetry: self.telemetry.unwrap_or(0),
            ..Status::default()
        }
    }
    fn apply(&mut self, s: &Settings, c: &Controller) -> Result<(), Refused> {
        self.lp.reconfigure(*c, s.limits)?;
        self.settings = *s;
        self.applied += 1;
        Ok(())
    }
    fn arm(&mut self) -> Result<(), Refused> {
        self.lp.arm()
    }
    fn disarm(&mut self) {
        self.lp.disarm()
    }
    fn goto(&mut self, x_m: f32) -> Result<(), Refused> {
        self.lp.goto(x_m)
    }
    fn sine(&mut self, a: f32, f: f32) -> Result<(), Refused> {
        self.lp.sine(a, f)
    }
    fn stop(&mut self) -> Result<(), Refused> {
        self.lp.stop()
    }
    fn clear(&mut self) -> Result<(), Refused> {
        self.lp.supervisor_mut().clear()
    }
    fn store(&mut self, image: &[u8]) -> Result<(), &'static str> {
        self.flash = Some(image.to_vec());
        Ok(())
    }
    fn load(&mut self, buf: &mut [u8]) -> bool {
        match &self.flash {
            Some(f) if f.len() == buf.len() => {
                buf.copy_from_slice(f);
                true
            }
            _ => false,
        }
    }
    fn telemetry(&mut self, d: Option<u32>) {
        self.telemetry = d;
    }
    fn hil(&mut self, on: bool) -> Result<(), Refused> {
        self.lp.supervisor().require_idle()?;
        self.hil = on;
        Ok(())
    }
    fn echo(&mut self, on: bool) {
        self.echo = on;
    }
    fn record_arm(
        &mut self,
        rows: u32,
        cal: &Calibration,
        controller: u8,
    ) -> Result<(), RecordError> {
        self.rec.arm(rows, cal, controller)
    }
    fn record_off(&mut self) {
        self.rec.off()
    }
    fn record_end(&mut self) {
        self.rec.end()
    }
    fn record_info(&mut self) -> RecordInfo {
        self.rec.info()
    }
    fn record_rows(&mut self, first: u32, out: &mut [PackedRow]) -> usize {
        self.rec.rows(first, out)
    }
}

/// A reply as the bytes the board sends.
#[derive(Default)]
struct Out(Vec<u8>);

impl std::fmt::Write for Out {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.0.extend_from_slice(s.as_bytes());
        Ok(())
    }
}

impl Output for Out {
    fn write_bytes(&mut self, bytes: &[u8]) {
        self.0.extend_from_slice(bytes);
    }
}

fn say_bytes(c: &mut Console, m: &mut Model, line: &str) -> Vec<u8> {
    let mut out = Out::default();
    c.execute(line, m, &mut out);
    out.0
}

fn say(c: &mut Console, m: &mut Model, line: &str) -> String {
    let out = say_bytes(c, m, line);
    String::from_utf8(out).expect("a text reply")
}

fn last_line(reply: &str) -> &str {
    assert!(reply.ends_with("\r\n"), "{reply:?}");
    reply.trim_end().rsplit("\r\n").next().unwrap()
}

fn ok(c: &mut Console, m: &mut Model, line: &str) -> String {
    let r = say(c, m, line);
    assert_eq!(last_line(&r), "ok", "{line:?} -> {r:?}");
    r
}

fn err(c: &mut Console, m: &mut Model, line: &str) -> String {
    let r = say(c, m, line);
    assert!(last_line(&r).starts_with("error: "), "{line:?} -> {r:?}");
    assert_eq!(r.matches("\r\n").count(), 1, "an error is one line: {r:?}");
    r
}

#[test]
fn every_reply_ends_with_ok_or_error() {
    let mut m = Model::new();
    let mut c = Console::new(m.settings);
    let help = ok(&mut c, &mut m, "help");
    assert!(help.lines().count() > 10);
    let st = ok(&mut c, &mut m, "status");
    assert!(
        st.starts_with("state=idle faults=none controller=mpc-eso"),
        "{st}"
    );
    assert_eq!(
        ok(&mut c, &mut m, "get eso.beta1"),
        "eso.beta1 = 30\r\nok\r\n"
    );
    assert_eq!(ok(&mut c, &mut m, "get pid.kp"), "pid.kp = 2.7\r\nok\r\n");
    assert_eq!(
        ok(&mut c, &mut m, "get cal.encoder.gain"),
        "cal.encoder.gain = 2e-7\r\nok\r\n"
    );
    let all = ok(&mut c, &mut m, "get");
    assert_eq!(all.lines().count(), dca_app::settings::PARAMS.len() + 1);
    assert_eq!(ok(&mut c, &mut m, "controller"), "mpc-eso\r\nok\r\n");
    assert!(ok(&mut c, &mut m, "fault").starts_with("faults=none\r\nlink good=0"));
}

#[test]
fn malformed_unknown_and_refused_lines_change_nothing() {
    let mut m = Model::new();
    let mut c = Console::new(m.settings);
    let before = *c.settings();
    for line in [
        "frobnicate",
        "set",
        "set eso.beta1",
        "set eso.beta1 abc",
        "set eso.beta1 1e999",
        "set eso.beta1 -5",
        "set eso.beta1 5 6",
        "set no.such 1",
        "set mpc_eso.np 8.5",
        "set mpc.np 1",
        "get no.such",
        "get a b",
        "goto",
        "goto 500",
        "goto -20",
        "goto x",
        "sine 10",
        "sine 0 1",
        "sine 10 0",
        "sine 10 50",
        "sine 80 1",
        "controller lqr",
        "controller pid extra",
        "preset slow",
        "telemetry",
        "telemetry maybe",
        "telemetry on 5",
        "telemetry on 100000",
        "telemetry on 1.5",
        "telemetry off 10",
        "hil",
        "hil maybe",
        "arm now",
        "load",
        "clear",
        "stop",
        "echo",
    ] {
        err(&mut c, &mut m, line);
        assert_eq!(*c.settings(), before, "{line}");
        assert_eq!(m.applied, 0, "{line}");
        assert_eq!(m.telemetry, None, "{line}");
        assert!(!m.hil, "{line}");
        assert_eq!(m.lp.supervisor().state(), State::Idle, "{line}");
    }
}

#[test]
fn settings_apply_only_when_idle_and_survive_store_and_load() {
    let mut m = Model::new();
    let mut c = Console::new(m.settings);
    ok(&mut c, &mut m, "set mpc_eso.rw 300");
    assert_eq!(m.settings.controller.mpc_eso.rw, 300.0);
    assert_eq!(m.applied, 1);
    ok(&mut c, &mut m, "controller pid");
    assert_eq!(m.lp.controller().kind(), ControllerKind::Pid);
    ok(&mut c, &mut m, "store");
    ok(&mut c, &mut m, "defaults");
    assert_eq!(m.settings.controller.kind, ControllerKind::MpcEso);
    ok(&mut c, &mut m, "load");
    assert_eq!(c.settings().controller.kind, ControllerKind::Pid);
    assert_eq!(c.settings().controller.mpc_eso.rw, 300.0);
    // Under control nothing may change.
    ok(&mut c, &mut m, "arm");
    let applied = m.applied;
    let r = err(&mut c, &mut m, "set pid.kp 3");
    assert_eq!(r, "error: disarm first\r\n");
    err(&mut c, &mut m, "preset fast");
    err(&mut c, &mut m, "hil on");
    assert_eq!(m.applied, applied);
    assert_eq!(c.settings().controller.pid.kp, 2.7);
    ok(&mut c, &mut m, "disarm");
    // A corrupt store is refused and leaves the settings.
    m.flash.as_mut().unwrap()[40] ^= 1;
    let r = err(&mut c, &mut m, "load");
    assert!(r.contains("checksum"), "{r}");
    assert_eq!(c.settings().controller.kind, ControllerKind::Pid);
}

#[test]
fn motion_commands_follow_the_supervisor() {
    let mut m = Model::new();
    let mut c = Console::new(m.settings);
    assert_eq!(err(&mut c, &mut m, "goto 10"), "error: not armed\r\n");
    ok(&mut c, &mut m, "arm");
    ok(&mut c, &mut m, "goto 10");
    assert_eq!(m.lp.reference_now(), 0.01);
    ok(&mut c, &mut m, "stop");
    ok(&mut c, &mut m, "sine 20 0.5");
    assert_eq!(m.lp.supervisor().state(), State::Running);
    err(&mut c, &mut m, "sine 50 0.5"); // 10 mm + 2 x 50 mm leaves the stroke
    ok(&mut c, &mut m, "telemetry on 10");
    assert_eq!(m.telemetry, Some(10));
    ok(&mut c, &mut m, "telemetry off");
    assert_eq!(m.telemetry, None);
    ok(&mut c, &mut m, "disarm");
    ok(&mut c, &mut m, "hil on");
    assert!(m.hil);
    ok(&mut c, &mut m, "echo on");
    assert!(m.echo);
}

#[test]
fn line_editor_handles_typing_garbage_and_overlong_lines() {
    let mut e = LineEditor::new();
    let mut feed = |bytes: &[u8]| -> Vec<String> {
        let mut lines = Vec::new();
        for &b in bytes {
            match e.push(b) {
                Edit::Line(s) => lines.push(s.to_string()),
                Edit::Bad(err) => lines.push(format!("!{}", err.as_str())),
                _ => {}
            }
        }
        lines
    };
    assert_eq!(feed(b"stat\x08\x08atus\r\n"), vec!["status"]);
    assert_eq!(feed(b"\r\n\r\n"), Vec::<String>::new());
    assert_eq!(feed(b"ge\x01t\n"), vec!["!invalid character in line"]);
    assert_eq!(
        feed("g\u{e9}t\n".as_bytes()),
        vec!["!invalid character in line"]
    );
    let long = vec![b'a'; MAX_LINE + 1];
    let mut bytes = long.clone();
    bytes.push(b'\n');
    assert_eq!(feed(&bytes), vec!["!line too long"]);
    let mut exact = vec![b'a'; MAX_LINE];
    exact.push(b'\r');
    assert_eq!(feed(&exact), vec!["a".repeat(MAX_LINE)]);
    assert_eq!(feed(b"help\n"), vec!["help"]);
}

#[test]
fn telemetry_rows_form_a_run_log() {
    let mut h = String::new();
    write_log_header(&mut h, "mpc-eso");
    assert!(h.starts_with("# dca-log v1\r\n# controller=mpc-eso\r\n"));
    let header = h.lines().find(|l| !l.starts_with('#')).unwrap();
    for col in [
        "t_s", "ref_m", "vcmd_mps", "xi_m", "xo_m", "p1_pa", "p2_pa", "ft_n",
    ] {
        assert!(header.split(',').any(|c| c == col), "{col}");
    }
    let mut b: Buf<160> = Buf::new();
    let row = LogRow {
        n: 1234,
        step_ms: 10,
        ref_m: 0.05,
        v_cmd_mps: -0.012,
        sample: Sample {
            xo_m: 0.0499,
            xi_m: 0.0415,
            p1_pa: 640_127.4,
            p2_pa: 1.0e6,
            ft_n: -3.25,
        },
        state: 2,
        faults: 0,
    };
    write_log_row(&mut b, &row);
    let line = b.as_str();
    assert!(
        line.starts_with("12.340,0.0500000,-0.0120000,0.04150000,0.04990000,640127.4,"),
        "{line}"
    );
    assert_eq!(line.split(',').count(), header.split(',').count());
    assert!(!b.overflowed());
}

/// What the console task gets from a receiver, as text (`!reason` for errors).
fn drain<const N: usize>(rx: &mut Receiver<N>) -> Vec<String> {
    let mut buf = [0u8; MAX_LINE];
    let mut got = Vec::new();
    while let Some(r) = rx.next(&mut buf) {
        got.push(match r {
            Received::Line(s) => s.to_string(),
            Received::Bad(e) => format!("!{}", e.as_str()),
        });
    }
    got
}

fn feed<const N: usize>(rx: &mut Receiver<N>, bytes: &[u8]) {
    for &b in bytes {
        rx.receive(b);
    }
}

#[test]
fn twenty_long_lines_pasted_at_once_all_arrive() {
    let mut rx: Receiver<RX_QUEUE_BYTES> = Receiver::new();
    let lines: Vec<String> = (0..20).map(|i| format!("set eso.beta1 {i:0>66}")).collect();
    assert!(lines.iter().all(|l| l.len() == MAX_LINE));
    for l in &lines {
        feed(&mut rx, l.as_bytes());
        feed(&mut rx, b"\r\n");
    }
    assert_eq!(drain(&mut rx), lines);
    assert_eq!(rx.discarded_total(), 0);
    assert_eq!(rx.queued_bytes(), 0);
}

#[test]
fn a_500_byte_paste_arrives_whole_or_as_one_error() {
    let mut rx: Receiver<RX_QUEUE_BYTES> = Receiver::new();
    // 50 short lines, 500 bytes with their CR LF.
    let paste: String = (0..50).map(|i| format!("get {i:0>4}\r\n")).collect();
    assert_eq!(paste.len(), 500);
    feed(&mut rx, paste.as_bytes());
    let got = drain(&mut rx);
    assert_eq!(got.len(), 50);
    assert_eq!(got[49], "get 0049");
    // One 500-character line: one error, and the next line is fine.
    feed(&mut rx, &[b'x'; 500]);
    feed(&mut rx, b"\r\nhelp\r\n");
    assert_eq!(drain(&mut rx), vec!["!line too long", "help"]);
}

#[test]
fn a_full_queue_answers_the_lines_that_did_not_fit_in_order() {
    let mut rx: Receiver<RX_QUEUE_BYTES> = Receiver::new();
    let line = "a".repeat(MAX_LINE);
    for _ in 0..40 {
        feed(&mut rx, line.as_bytes());
        feed(&mut rx, b"\n");
    }
    let fit = RX_QUEUE_BYTES / (MAX_LINE + 1);
    // The console takes one line; the next line typed is still discarded:
    // it would otherwise be answered before the ones that did not fit.
    let mut buf = [0u8; MAX_LINE];
    assert!(matches!(rx.next(&mut buf), Some(Received::Line(_))));
    feed(&mut rx, b"status\n");
    let got = drain(&mut rx);
    assert_eq!(got.len(), 40);
    assert!(got[..fit - 1].iter().all(|l| *l == line));
    assert!(got[fit - 1..]
        .iter()
        .all(|l| l == "!input queue full, line discarded"));
    assert_eq!(rx.discarded_total() as usize, 41 - fit);
    // Drained: lines are queued again.
    feed(&mut rx, b"status\n");
    assert_eq!(drain(&mut rx), vec!["status"]);
}

#[test]
fn lost_bytes_are_answered_never_silent() {
    let mut rx: Receiver<RX_QUEUE_BYTES> = Receiver::new();
    feed(&mut rx, b"got");
    rx.lost();
    feed(&mut rx, b"o 10\r\n");
    // Even a line of which nothing but the end arrived.
    rx.lost();
    feed(&mut rx, b"\n");
    assert_eq!(
        drain(&mut rx),
        vec![
            "!input overrun, line discarded",
            "!input overrun, line discarded"
        ]
    );
    assert_eq!(LineError::Overrun.as_str(), "input overrun, line discarded");
}

#[test]
fn echo_comes_before_the_line_and_is_best_effort() {
    let mut rx: Receiver<RX_QUEUE_BYTES> = Receiver::new();
    feed(&mut rx, b"ab");
    assert_eq!(rx.next_echo(), None, "echo is off by default");
    rx.set_echo(true);
    feed(&mut rx, b"c\x08d\r");
    let echo: Vec<u8> = std::iter::from_fn(|| rx.next_echo()).collect();
    assert_eq!(echo, b"c\x08 \x08d\r\n");
    assert_eq!(drain(&mut rx), vec!["abd"]);
    // A long paste overflows the echo queue, not the line queue.
    let long = "b".repeat(MAX_LINE);
    feed(&mut rx, long.as_bytes());
    feed(&mut rx, b"\r");
    assert_eq!(drain(&mut rx), vec![long]);
}

/// The replies a console gives to `bytes`, from the line editor alone
/// (no queue): what the receiver must reproduce, up to discarded lines.
fn expected(bytes: &[u8]) -> Vec<String> {
    let mut e = LineEditor::new();
    let mut out = Vec::new();
    for &b in bytes {
        match e.push(b) {
            Edit::Line(s) => out.push(s.to_string()),
            Edit::Bad(err) => out.push(format!("!{}", err.as_str())),
            _ => {}
        }
    }
    out
}

proptest! {
    /// Any input, taken by the console task at any moments: every line gets
    /// exactly one reply, in order, the line itself unless it did not fit.
    #[test]
    fn every_line_gets_exactly_one_reply_in_order(
        chunks in prop::collection::vec(
            (prop::collection::vec(
                prop_oneof![
                    8 => 0x20u8..0x7f,
                    2 => Just(b'\n'),
                    1 => Just(b'\r'),
                    1 => Just(0x08u8),
                    1 => any::<u8>(),
                ],
                0..300,
            ), 0usize..4),
            1..40,
        ),
    ) {
        // A small queue, so that it overflows often.
        let mut rx: Receiver<256> = Receiver::new();
        let mut all = Vec::new();
        let mut got = Vec::new();
        let mut buf = [0u8; MAX_LINE];
        for (bytes, takes) in &chunks {
            feed(&mut rx, bytes);
            all.extend_from_slice(bytes);
            for _ in 0..*takes {
                match rx.next(&mut buf) {
                    Some(Received::Line(s)) => got.push(s.to_string()),
                    Some(Received::Bad(e)) => got.push(format!("!{}", e.as_str())),
                    None => break,
                }
            }
        }
        got.extend(drain(&mut rx));
        let want = expected(&all);
        prop_assert_eq!(got.len(), want.len());
        let discarded = "!input queue full, line discarded";
        for (g, w) in got.iter().zip(&want) {
            prop_assert!(g == w || g == discarded, "{:?} for {:?}", g, w);
        }
        prop_assert_eq!(rx.queued_bytes(), 0);
    }
}

#[test]
fn the_command_table_drives_help_and_usage() {
    let mut m = Model::new();
    let mut c = Console::new(m.settings);
    let help = ok(&mut c, &mut m, "help");
    let lines: Vec<&str> = help.lines().collect();
    assert_eq!(lines.len(), COMMANDS.len() + 1, "{help}");
    for (cmd, line) in COMMANDS.iter().zip(&lines) {
        assert!(
            line.starts_with(&format!("{} ", cmd.name))
                || line.starts_with(&format!("{}:", cmd.name)),
            "{line}"
        );
        assert!(line.ends_with(cmd.help), "{line}");
        let usage = if cmd.args.is_empty() {
            format!("error: usage: {}\r\n", cmd.name)
        } else {
            format!("error: usage: {} {}\r\n", cmd.name, cmd.args)
        };
        // Too many arguments: always the command's own usage.
        let extra = format!("{} a b c d", cmd.name);
        assert_eq!(err(&mut c, &mut m, &extra), usage, "{extra}");
        if cmd.required > 0 {
            assert_eq!(err(&mut c, &mut m, cmd.name), usage, "{}", cmd.name);
        }
    }
    let mut names: Vec<&str> = COMMANDS.iter().map(|c| c.name).collect();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), COMMANDS.len(), "command names are unique");
    assert_eq!(m.applied, 0);
}

/// docs/firmware.md shows `help`'s output; it must be the table's.
#[test]
fn the_manual_shows_the_help_the_console_prints() {
    let mut m = Model::new();
    let mut c = Console::new(m.settings);
    let help = ok(&mut c, &mut m, "help");
    let printed: Vec<&str> = help.lines().filter(|l| *l != "ok").collect();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/firmware.md");
    let manual = std::fs::read_to_string(path).unwrap();
    let start = manual
        .find("```text\nhelp: ")
        .expect("docs/firmware.md shows the help output")
        + "```text\n".len();
    let end = start + manual[start..].find("```").unwrap();
    let shown: Vec<&str> = manual[start..end].lines().collect();
    assert_eq!(
        shown, printed,
        "update the console section of docs/firmware.md"
    );
}

/// A dump read back: its head and its rows, every frame checked.
fn read_dump(reply: &[u8]) -> (RecordHead, Vec<PackedRow>) {
    let nl = reply.iter().position(|b| *b == b'\n').unwrap();
    let first = std::str::from_utf8(&reply[..nl]).unwrap().trim_end();
    let mut it = first.strip_prefix("dump rows=").unwrap().split(" frames=");
    let rows: u32 = it.next().unwrap().parse().unwrap();
    let frames: u32 = it.next().unwrap().parse().unwrap();
    let mut rest = reply[nl + 1..].to_vec();
    let mut bodies = Vec::new();
    for _ in 0..frames {
        let end = rest.iter().position(|b| *b == 0).unwrap();
        bodies.push(rest[..end].to_vec());
        rest.drain(..=end);
    }
    assert_eq!(rest, b"ok\r\n");
    let head: RecordHead = frame::decode(&mut bodies[0]).unwrap();
    assert_eq!((head.rows, head.frames()), (rows, frames));
    let mut out = Vec::new();
    for (k, body) in bodies[1..].iter_mut().enumerate() {
        let chunk: RecordChunk = frame::decode(body).unwrap();
        assert_eq!(chunk.seq as usize, k + 1);
        out.extend_from_slice(&chunk.rows);
    }
    out.truncate(rows as usize);
    (head, out)
}

#[test]
fn a_record_starts_with_the_motion_takes_every_tick_and_dumps_as_frames() {
    let mut m = Model::new();
    let mut c = Console::new(m.settings);
    assert_eq!(
        last_line(&say(&mut c, &mut m, "dump")),
        "error: nothing recorded"
    );
    // 12 rows of 1 ms fit; 13 do not.
    assert!(say(&mut c, &mut m, "record 0.013").starts_with("error: record length"));
    assert!(say(&mut c, &mut m, "record 0").starts_with("error: record length"));
    ok(&mut c, &mut m, "record 0.010");
    let st = ok(&mut c, &mut m, "record");
    assert!(
        st.starts_with("record=armed rows=0 of 10 capacity=12 rows"),
        "{st}"
    );
    ok(&mut c, &mut m, "arm");
    let sample = |k: usize| Sample {
        xo_m: 0.001 * k as f32,
        xi_m: 0.0011 * k as f32,
        p1_pa: 1.0e6 + 1.0e4 * k as f32,
        p2_pa: 2.0e6,
        ft_n: -10.0 * k as f32,
    };
    // Armed, not moving: nothing recorded yet.
    for k in 0..3 {
        m.tick(&sample(k));
    }
    assert_eq!(m.rec.info().rows, 0);
    ok(&mut c, &mut m, "goto 20");
    let mut want = Vec::new();
    for k in 0..15 {
        let s = sample(k);
        let v = m.tick(&s);
        want.push((m.lp.last_ref_m(), v, s));
    }
    let st = ok(&mut c, &mut m, "record");
    assert!(st.starts_with("record=done rows=10 of 10"), "{st}");
    let reply = say_bytes(&mut c, &mut m, "dump");
    let (head, rows) = read_dump(&reply);
    assert_eq!(rows.len(), 10);
    assert_eq!(head.frames() as usize, 1 + 10_usize.div_ceil(CHUNK_ROWS));
    let cal = m.settings.cal;
    for (k, (row, (ref_m, v, s))) in rows.iter().zip(&want).enumerate() {
        let r = head.row(row);
        assert!(
            (r.ref_m - f64::from(*ref_m)).abs() <= REF_LSB_M / 2.0,
            "row {k}"
        );
        assert!(
            (r.v_cmd_mps - f64::from(*v)).abs() <= VCMD_LSB_MPS / 2.0,
            "row {k}"
        );
        for (got, v, ch) in [
            (r.sample.xo_m, s.xo_m, cal.lvdt),
            (r.sample.p1_pa, s.p1_pa, cal.p1),
            (r.sample.p2_pa, s.p2_pa, cal.p2),
            (r.sample.ft_n, s.ft_n, cal.force),
            (r.sample.xi_m, s.xi_m, cal.encoder),
        ] {
            assert!(
                (got - v).abs() <= 0.5001 * ch.gain,
                "row {k}: {got} for {v} (one code {})",
                ch.gain
            );
        }
    }
    // A second dump sends the same record; `record off` drops it.
    assert_eq!(say_bytes(&mut c, &mut m, "dump"), reply);
    ok(&mut c, &mut m, "record off");
    assert_eq!(
        last_line(&say(&mut c, &mut m, "dump")),
        "error: nothing recorded"
    );
}

#[test]
fn dump_ends_a_record_being_taken_and_sends_what_it_has() {
    let mut m = Model::new();
    let mut c = Console::new(m.settings);
    ok(&mut c, &mut m, "record 0.012");
    ok(&mut c, &mut m, "arm");
    ok(&mut c, &mut m, "goto 10");
    for _ in 0..8 {
        m.tick(&Sample::default());
    }
    let (head, rows) = read_dump(&say_bytes(&mut c, &mut m, "dump"));
    assert_eq!((head.rows, rows.len()), (8, 8));
    // Ended: later ticks are not recorded.
    m.tick(&Sample::default());
    assert_eq!(m.rec.info().rows, 8);
}

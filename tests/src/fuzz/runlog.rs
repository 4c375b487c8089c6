//! Run logs: [`RunLog::parse`] on arbitrary text (the input as UTF-8, invalid
//! sequences replaced).
//!
//! Invariants (what `host_sim::io::runlog` promises):
//! * no panic;
//! * an accepted log has the eight required columns and every optional one
//!   of its header, all of one length (at least two rows), only finite
//!   values, and a time column that is strictly increasing with a finite
//!   step, uniform to within [`DT_REL_TOL`] of the first step;
//! * a refused log's error names the file, and a line (when it gives one)
//!   that exists in the text;
//! * line ends do not matter: the same text with CR LF line ends gives the
//!   same log or the same error; nor does a UTF-8 byte-order mark before it;
//! * the gap diagnosis's reader ([`RunLog::parse_with`] with
//!   [`LOG_STEPS`]) accepts exactly the logs whose step is within its range,
//!   the same log; a log refused for its step is refused at its second data
//!   row, in the column `t_s`, with the range in the message.

use host_sim::gap::replay::LOG_STEPS;
use host_sim::io::runlog::{LogError, RunLog, DT_REL_TOL, REQUIRED};

use super::{line_limit, text};

const FILE: &str = "fuzz.csv";

fn check_ok(log: &RunLog) {
    let n = log.len();
    assert!(n >= 2, "a log of {n} rows accepted");
    for name in REQUIRED {
        let c = log.channel(name).expect("required channels exist");
        assert_eq!(c.len(), n, "column {name}");
        assert!(c.iter().all(|v| v.is_finite()), "column {name}: {c:?}");
    }
    for (name, c) in &log.extra {
        assert_eq!(c.len(), n, "column {name}");
        assert!(c.iter().all(|v| v.is_finite()), "column {name}: {c:?}");
        assert!(!REQUIRED.contains(&name.as_str()), "{name} is required");
    }
    let t = &log.t_s;
    let d0 = t[1] - t[0];
    assert!(d0 > 0.0 && d0.is_finite(), "first time step {d0}");
    assert_eq!(log.dt_s(), d0);
    for (k, w) in t.windows(2).enumerate() {
        let d = w[1] - w[0];
        assert!(
            d > 0.0 && d.is_finite(),
            "time step {d} at row {k}: {} -> {}",
            w[0],
            w[1]
        );
        assert!(
            (d - d0).abs() <= DT_REL_TOL * d0,
            "time step {d} at row {k}, the log's step is {d0}"
        );
    }
}

fn check_err(e: &LogError, text: &str) {
    assert_eq!(e.file, FILE);
    assert!(e.to_string().starts_with(FILE), "{e}");
    assert!(!e.message.is_empty(), "{e:?}");
    if let Some(l) = e.line {
        assert!(
            l >= 1 && l as usize <= line_limit(text),
            "line {l} of a text of {} lines: {e}",
            text.lines().count()
        );
    }
}

/// The gap's reader agrees with the general one but for the step's range.
fn check_gap_reader(text: &str, any: &Result<RunLog, LogError>) {
    let gap = RunLog::parse_with(text, FILE, &LOG_STEPS);
    match (any, &gap) {
        (Ok(log), Ok(g)) => {
            assert_eq!(log, g, "the gap's reader read another log");
            assert!(
                LOG_STEPS.contains(log.dt_s()),
                "step {} accepted",
                log.dt_s()
            );
        }
        (Ok(log), Err(e)) => {
            check_err(e, text);
            assert!(
                !LOG_STEPS.contains(log.dt_s()),
                "step {} refused: {e}",
                log.dt_s()
            );
            assert_eq!(e.column.as_deref(), Some("t_s"), "{e}");
            assert!(e.message.contains("outside"), "{e}");
        }
        (Err(_), Ok(g)) => panic!("the gap's reader accepted a refused log: {g:?}"),
        (Err(_), Err(e)) => check_err(e, text),
    }
}

/// The run-log harness; see the module documentation.
pub fn runlog(data: &[u8]) {
    let text = text(data);
    let r = RunLog::parse(&text, FILE);
    match &r {
        Ok(log) => check_ok(log),
        Err(e) => check_err(e, &text),
    }
    check_gap_reader(&text, &r);
    if !text.starts_with('\u{feff}') {
        let bom = format!("\u{feff}{text}");
        assert_eq!(
            RunLog::parse(&bom, FILE),
            r,
            "a byte-order mark changes the result"
        );
    }
    if !text.contains('\r') {
        let crlf = text.replace('\n', "\r\n");
        assert_eq!(
            RunLog::parse(&crlf, FILE),
            r,
            "CR LF line ends change the result"
        );
    }
}

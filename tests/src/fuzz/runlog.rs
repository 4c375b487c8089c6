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
//!   same log or the same error.

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

/// The run-log harness; see the module documentation.
pub fn runlog(data: &[u8]) {
    let text = text(data);
    let r = RunLog::parse(&text, FILE);
    match &r {
        Ok(log) => check_ok(log),
        Err(e) => check_err(e, &text),
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

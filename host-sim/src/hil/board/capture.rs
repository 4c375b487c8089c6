//! Telemetry captured from the console, written as a run log.
//!
//! After `telemetry on [decimation]` the board streams the run log of
//! docs/interfaces.md section 1 on its console: `# dca-log v1`, metadata, the
//! header and one row every `decimation` control ticks (1 ms each), stamped
//! `n * decimation` ms exactly. At 115 200 baud a row of about 80 characters
//! leaves room for at most about 100 rows a second, so the firmware accepts
//! decimations from 10 (a 10 ms step) up. A [`Capture`] checks that the rows
//! are evenly spaced, so that what it writes is a run log `host-sim gap` reads
//! as it is; a missing row (the board's queue overflowed) ends the capture at
//! the gap and is reported.

use std::io::Write;
use std::path::Path;

use crate::io::files::{self, PathError};

/// Why a capture could not be written as a run log.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    /// No stream started.
    #[error("no telemetry stream was captured (send `telemetry on` first)")]
    NoStream,
    /// Fewer than two rows.
    #[error("the telemetry stream has {0} row(s); a run log needs at least 2")]
    TooShort(usize),
    /// The file.
    #[error(transparent)]
    File(#[from] PathError),
}

/// One telemetry stream being captured.
#[derive(Clone, Debug, Default)]
pub struct Capture {
    meta: Vec<String>,
    header: Option<String>,
    rows: Vec<String>,
    /// Time of the first and last kept rows, ms.
    first_ms: Option<u64>,
    last_ms: Option<u64>,
    step_ms: Option<u64>,
    /// The gap that ended the capture: (last kept row, row after it), s.
    gap: Option<(f64, f64)>,
    /// Streams started (a second `telemetry on` replaces the first).
    streams: usize,
    /// Rows that could not be read.
    bad_rows: usize,
}

/// A row's time stamp `s.mmm` in ms.
fn stamp_ms(row: &str) -> Option<u64> {
    let t = row.split(',').next()?;
    let (s, ms) = t.split_once('.')?;
    if ms.len() != 3 {
        return None;
    }
    Some(s.parse::<u64>().ok()? * 1000 + ms.parse::<u64>().ok()?)
}

impl Capture {
    /// Nothing captured yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feed one stream line (without its line end).
    pub fn line(&mut self, line: &str) {
        if line == "# dca-log v1" {
            let streams = self.streams + 1;
            *self = Self {
                streams,
                ..Self::default()
            };
            return;
        }
        if self.streams == 0 {
            // Rows of a stream whose start was not seen: not a run log.
            return;
        }
        if let Some(m) = line.strip_prefix('#') {
            if self.header.is_none() {
                self.meta.push(m.trim().to_string());
            }
            return;
        }
        if line.starts_with("t_s,") {
            self.header = Some(line.to_string());
            return;
        }
        if self.header.is_none() || self.gap.is_some() {
            return;
        }
        let Some(t) = stamp_ms(line) else {
            self.bad_rows += 1;
            return;
        };
        match (self.last_ms, self.step_ms) {
            (None, _) => self.first_ms = Some(t),
            (Some(last), None) if t > last => self.step_ms = Some(t - last),
            (Some(last), Some(step)) if t == last + step => {}
            (Some(last), _) => {
                self.gap = Some((last as f64 / 1e3, t as f64 / 1e3));
                return;
            }
        }
        self.last_ms = Some(t);
        self.rows.push(line.to_string());
    }

    /// Rows kept.
    pub fn rows(&self) -> usize {
        self.rows.len()
    }

    /// The time step of the rows, s (once two rows arrived).
    pub fn step_s(&self) -> Option<f64> {
        self.step_ms.map(|s| s as f64 / 1e3)
    }

    /// Telemetry streams seen (only the last is kept).
    pub fn streams(&self) -> usize {
        self.streams
    }

    /// Where rows went missing, if they did: the last kept row's time and
    /// the next row's, s.
    pub fn gap(&self) -> Option<(f64, f64)> {
        self.gap
    }

    /// Rows whose time stamp could not be read (skipped).
    pub fn bad_rows(&self) -> usize {
        self.bad_rows
    }

    /// Write the run log: the board's metadata, `extra` metadata, the header
    /// and the rows. Fails when no header or fewer than two rows arrived.
    pub fn write(&self, path: &Path, extra: &[(&str, String)]) -> Result<(), CaptureError> {
        let Some(header) = &self.header else {
            return Err(CaptureError::NoStream);
        };
        if self.rows.len() < 2 {
            return Err(CaptureError::TooShort(self.rows.len()));
        }
        let mut out = String::from("# dca-log v1\n");
        for m in &self.meta {
            out.push_str(&format!("# {m}\n"));
        }
        for (k, v) in extra {
            out.push_str(&format!("# {k}={v}\n"));
        }
        if let Some(step) = self.step_s() {
            out.push_str(&format!("# step_s={step}\n"));
        }
        out.push_str(header);
        out.push('\n');
        for r in &self.rows {
            out.push_str(r);
            out.push('\n');
        }
        let mut f = files::create(path)?;
        f.write_all(out.as_bytes())
            .map_err(|e| PathError::new(path, e))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(t_ms: u64) -> String {
        format!(
            "{}.{:03},0.0100000,0.0000000,0.00000000,0.00000000,1000000.0,1000000.0,0.00,1,0",
            t_ms / 1000,
            t_ms % 1000
        )
    }

    fn stream(c: &mut Capture, times: &[u64]) {
        c.line("# dca-log v1");
        c.line("# controller=mpc-eso");
        c.line("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n,state,faults");
        for t in times {
            c.line(&row(*t));
        }
    }

    #[test]
    fn an_even_stream_becomes_a_run_log_the_reader_accepts() {
        let mut c = Capture::new();
        c.line(&row(0)); // before any stream: ignored
        stream(&mut c, &[0, 10, 20, 30]);
        assert_eq!((c.rows(), c.step_s(), c.gap()), (4, Some(0.01), None));
        let dir = std::env::temp_dir().join(format!("capture-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("run.csv");
        c.write(&p, &[("port", "/dev/pts/9".into())]).unwrap();
        let log = crate::io::runlog::RunLog::read(&p).unwrap();
        assert_eq!(log.len(), 4);
        assert!((log.dt_s() - 0.01).abs() < 1e-12);
        assert_eq!(log.meta("port"), Some("/dev/pts/9"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_row_ends_the_capture_and_says_where() {
        let mut c = Capture::new();
        stream(&mut c, &[0, 10, 20, 40, 50]);
        assert_eq!(c.rows(), 3);
        assert_eq!(c.gap(), Some((0.02, 0.04)));
        // A new stream starts afresh.
        stream(&mut c, &[0, 100, 200]);
        assert_eq!((c.rows(), c.gap(), c.streams()), (3, None, 2));
        assert!(Capture::new()
            .write(Path::new("/nonexistent/x.csv"), &[])
            .is_err());
    }
}

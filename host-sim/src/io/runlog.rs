//! Run logs: the CSV format of docs/interfaces.md section 1, written and read.
//!
//! ```text
//! # dca-log v1
//! # controller=mpc-eso
//! t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n
//! 0.000,0.050000,0.000000,0.0000000,0.0000000,640127.4,1000000.0,0.0
//! ```
//!
//! The reader accepts the required columns in any order, keeps optional
//! columns it finds (by name), skips a UTF-8 byte-order mark (spreadsheet
//! programs write one), and rejects with an error naming the file, the line
//! and the column: a missing required column, a value that is not a finite
//! number, a row with the wrong number of fields, and a time column that is
//! not strictly increasing with a uniform step. A reader that can use only
//! some steps ([`RunLog::parse_with`], [`StepRange`]) also rejects a step
//! outside them, and says so with the range and why. It never drops or
//! reorders rows.

use std::collections::BTreeMap;
use std::fmt;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::num::Num;

/// The required columns, in the order the writer puts them.
pub const REQUIRED: [&str; 8] = [
    "t_s", "ref_m", "vcmd_mps", "xi_m", "xo_m", "p1_pa", "p2_pa", "ft_n",
];

/// Relative tolerance on the time step: a step that differs from the first by
/// more than this fraction of it makes the time column non-uniform.
pub const DT_REL_TOL: f64 = 1e-3;

/// The time steps a consumer of run logs can use, with the reason (for the
/// error that refuses a log outside them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepRange {
    /// Smallest step, s (every step must also be > 0).
    pub min_dt_s: f64,
    /// Largest step, s.
    pub max_dt_s: f64,
    /// Who needs the range and why, completing "... is outside the range
    /// of `why`", e.g. "the gap diagnosis (...)".
    pub why: &'static str,
}

impl StepRange {
    /// Any positive, finite step (what [`RunLog::parse`] accepts).
    pub const ANY: StepRange = StepRange {
        min_dt_s: 0.0,
        max_dt_s: f64::MAX,
        why: "any reader",
    };

    /// Whether `dt_s` is in the range, ends included to within
    /// [`DT_REL_TOL`] (a 10 ms step written with rounded times is 10 ms).
    pub fn contains(&self, dt_s: f64) -> bool {
        dt_s >= self.min_dt_s * (1.0 - DT_REL_TOL) && dt_s <= self.max_dt_s * (1.0 + DT_REL_TOL)
    }

    /// Why `dt_s` is refused, with a hint when the time column looks like
    /// milliseconds (the step divided by 1000 would be in the range).
    fn refusal(&self, dt_s: f64) -> String {
        let mut m = format!(
            "time step {} s is outside {} to {} s, the range of {}",
            Num(dt_s),
            Num(self.min_dt_s),
            Num(self.max_dt_s),
            self.why
        );
        if self.contains(dt_s / 1000.0) {
            m += &format!(
                "; t_s is in seconds: if this column is in milliseconds, divide it by 1000 \
                 (a step of {} s)",
                Num(dt_s / 1000.0)
            );
        }
        m
    }
}

/// A run log in memory: metadata, the required channels and optional ones.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunLog {
    /// Where it came from (for messages), if read from a file.
    pub source: Option<PathBuf>,
    /// `# key=value` metadata lines, in order.
    pub meta: Vec<(String, String)>,
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Reference, m.
    pub ref_m: Vec<f64>,
    /// Drive speed command, m/s.
    pub vcmd_mps: Vec<f64>,
    /// Power piston position (encoder), m.
    pub xi_m: Vec<f64>,
    /// Actuating piston position (LVDT), m.
    pub xo_m: Vec<f64>,
    /// Line-1 pressure, Pa.
    pub p1_pa: Vec<f64>,
    /// Line-2 pressure, Pa.
    pub p2_pa: Vec<f64>,
    /// Load force, N.
    pub ft_n: Vec<f64>,
    /// Optional columns by name.
    pub extra: BTreeMap<String, Vec<f64>>,
}

/// A log that could not be read or written; names file, line and column.
#[derive(Clone, Debug, PartialEq)]
pub struct LogError {
    /// The file.
    pub file: String,
    /// 1-based line number, when the problem is on a line.
    pub line: Option<u64>,
    /// The column concerned, when there is one.
    pub column: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for LogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        if let Some(c) = &self.column {
            write!(f, ": column '{c}'")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for LogError {}

impl RunLog {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when the log has no rows.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// The sample period, s (0 for fewer than two rows).
    pub fn dt_s(&self) -> f64 {
        if self.t_s.len() < 2 {
            0.0
        } else {
            self.t_s[1] - self.t_s[0]
        }
    }

    /// Every `n`-th row from the first (`n` >= 1), as the board's console
    /// records a run at 1/n of its tick rate (docs/interfaces.md section 5);
    /// metadata and extra columns kept.
    pub fn decimate(&self, n: usize) -> RunLog {
        let n = n.max(1);
        let every = |v: &[f64]| v.iter().step_by(n).copied().collect::<Vec<_>>();
        RunLog {
            source: self.source.clone(),
            meta: self.meta.clone(),
            t_s: every(&self.t_s),
            ref_m: every(&self.ref_m),
            vcmd_mps: every(&self.vcmd_mps),
            xi_m: every(&self.xi_m),
            xo_m: every(&self.xo_m),
            p1_pa: every(&self.p1_pa),
            p2_pa: every(&self.p2_pa),
            ft_n: every(&self.ft_n),
            extra: self
                .extra
                .iter()
                .map(|(k, v)| (k.clone(), every(v)))
                .collect(),
        }
    }

    /// A metadata value.
    pub fn meta(&self, key: &str) -> Option<&str> {
        self.meta
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// The channel called `name` (required or optional).
    pub fn channel(&self, name: &str) -> Option<&[f64]> {
        Some(match name {
            "t_s" => &self.t_s,
            "ref_m" => &self.ref_m,
            "vcmd_mps" => &self.vcmd_mps,
            "xi_m" => &self.xi_m,
            "xo_m" => &self.xo_m,
            "p1_pa" => &self.p1_pa,
            "p2_pa" => &self.p2_pa,
            "ft_n" => &self.ft_n,
            other => return self.extra.get(other).map(|v| v.as_slice()),
        })
    }

    fn required_mut(&mut self, i: usize) -> &mut Vec<f64> {
        match i {
            0 => &mut self.t_s,
            1 => &mut self.ref_m,
            2 => &mut self.vcmd_mps,
            3 => &mut self.xi_m,
            4 => &mut self.xo_m,
            5 => &mut self.p1_pa,
            6 => &mut self.p2_pa,
            _ => &mut self.ft_n,
        }
    }

    /// Write the log as CSV.
    pub fn write(&self, path: &Path) -> Result<(), LogError> {
        let io = |e: std::io::Error| LogError {
            file: path.display().to_string(),
            line: None,
            column: None,
            message: e.to_string(),
        };
        let f = std::fs::File::create(path).map_err(io)?;
        let mut w = BufWriter::new(f);
        self.write_to(&mut w).map_err(io)?;
        w.flush().map_err(io)
    }

    /// Write the log as CSV to any writer.
    pub fn write_to(&self, w: &mut impl Write) -> std::io::Result<()> {
        writeln!(w, "# dca-log v1")?;
        for (k, v) in &self.meta {
            writeln!(w, "# {k}={v}")?;
        }
        let extras: Vec<&String> = self.extra.keys().collect();
        let mut header: Vec<&str> = REQUIRED.to_vec();
        header.extend(extras.iter().map(|s| s.as_str()));
        writeln!(w, "{}", header.join(","))?;
        for i in 0..self.len() {
            write!(
                w,
                "{:.4},{:.9},{:.9},{:.9},{:.9},{:.1},{:.1},{:.3}",
                self.t_s[i],
                self.ref_m[i],
                self.vcmd_mps[i],
                self.xi_m[i],
                self.xo_m[i],
                self.p1_pa[i],
                self.p2_pa[i],
                self.ft_n[i]
            )?;
            for name in &extras {
                write!(w, ",{}", self.extra[*name][i])?;
            }
            writeln!(w)?;
        }
        Ok(())
    }

    /// Read a log file.
    pub fn read(path: &Path) -> Result<Self, LogError> {
        Self::read_with(path, &StepRange::ANY)
    }

    /// Read a log file whose time step must be within `steps`.
    pub fn read_with(path: &Path, steps: &StepRange) -> Result<Self, LogError> {
        let text = std::fs::read_to_string(path).map_err(|e| LogError {
            file: path.display().to_string(),
            line: None,
            column: None,
            message: e.to_string(),
        })?;
        let mut log = Self::parse_with(&text, &path.display().to_string(), steps)?;
        log.source = Some(path.to_path_buf());
        Ok(log)
    }

    /// Parse log text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, LogError> {
        Self::parse_with(text, file, &StepRange::ANY)
    }

    /// Parse log text whose time step must be within `steps`; `file` names
    /// it in errors.
    pub fn parse_with(text: &str, file: &str, steps: &StepRange) -> Result<Self, LogError> {
        // A byte-order mark is not part of the first column's name.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let err = |line: Option<u64>, column: Option<&str>, message: String| LogError {
            file: file.to_string(),
            line,
            column: column.map(str::to_string),
            message,
        };
        let mut log = RunLog::default();
        let mut lines = text.lines().enumerate().map(|(i, l)| (i as u64 + 1, l));
        // Metadata until the header (the first line not starting with '#').
        let (header_line, header) = loop {
            match lines.next() {
                None => return Err(err(None, None, "no header line".into())),
                Some((_, l)) if l.trim_start().starts_with('#') => {
                    if let Some((k, v)) = l.trim_start()[1..].trim().split_once('=') {
                        log.meta.push((k.trim().to_string(), v.trim().to_string()));
                    }
                }
                Some((n, l)) if l.trim().is_empty() => {
                    return Err(err(Some(n), None, "empty line before the header".into()))
                }
                Some((n, l)) => break (n, l),
            }
        };
        let names: Vec<String> = header.split(',').map(|s| s.trim().to_string()).collect();
        let slot = column_slots(&names, &|c, m| err(Some(header_line), c, m))?;
        for (i, n) in names.iter().enumerate() {
            if slot[i].is_none() {
                log.extra.insert(n.clone(), Vec::new());
            }
        }
        let t_col = &names[names.iter().position(|n| n == "t_s").unwrap_or(0)];
        let mut dt0: Option<f64> = None;
        for (n, l) in lines {
            if l.trim().is_empty() {
                continue;
            }
            if l.trim_start().starts_with('#') {
                return Err(err(
                    Some(n),
                    None,
                    "comment line after the header (metadata belongs before it)".into(),
                ));
            }
            let at = |column: Option<&str>, message: String| err(Some(n), column, message);
            log.push_row(l, &names, &slot, &at)?;
            log.check_time_step(&mut dt0, steps, &|m| at(Some(t_col), m))?;
        }
        if log.t_s.len() < 2 {
            return Err(err(None, None, "fewer than two data rows".into()));
        }
        Ok(log)
    }

    /// Append the fields of one data row (`slot`: the required channel of
    /// each column, or an optional column); `at` makes the error of a column
    /// (if one) of this line.
    fn push_row(
        &mut self,
        line: &str,
        names: &[String],
        slot: &[Option<usize>],
        at: &dyn Fn(Option<&str>, String) -> LogError,
    ) -> Result<(), LogError> {
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != names.len() {
            return Err(at(
                None,
                format!(
                    "{} fields, but the header has {} columns",
                    fields.len(),
                    names.len()
                ),
            ));
        }
        for (i, f) in fields.iter().enumerate() {
            let v: f64 = f
                .trim()
                .parse()
                .map_err(|_| at(Some(&names[i]), format!("'{}' is not a number", f.trim())))?;
            if !v.is_finite() {
                return Err(at(
                    Some(&names[i]),
                    format!("'{}' is not a finite number", f.trim()),
                ));
            }
            match slot[i] {
                Some(r) => self.required_mut(r).push(v),
                None => self.extra.get_mut(&names[i]).expect("inserted").push(v),
            }
        }
        Ok(())
    }

    /// Check the step between the last two times: increasing, finite, and
    /// within [`DT_REL_TOL`] of the first step `dt0` (set by the first call
    /// with two rows), which must be within `steps`; `at` makes the error of
    /// the time column.
    fn check_time_step(
        &self,
        dt0: &mut Option<f64>,
        steps: &StepRange,
        at: &dyn Fn(String) -> LogError,
    ) -> Result<(), LogError> {
        let t = &self.t_s;
        if t.len() < 2 {
            return Ok(());
        }
        let dt = t[t.len() - 1] - t[t.len() - 2];
        if dt <= 0.0 {
            return Err(at(format!(
                "time {} does not increase (previous {})",
                Num(t[t.len() - 1]),
                Num(t[t.len() - 2])
            )));
        }
        if !dt.is_finite() {
            return Err(at(format!(
                "time step from {} to {} is not a finite number",
                Num(t[t.len() - 2]),
                Num(t[t.len() - 1])
            )));
        }
        if dt0.is_none() && !steps.contains(dt) {
            return Err(at(steps.refusal(dt)));
        }
        let d0 = *dt0.get_or_insert(dt);
        if (dt - d0).abs() > DT_REL_TOL * d0 {
            return Err(at(format!(
                "non-uniform time step {} s (the log's step is {} s)",
                Num(dt),
                Num(d0)
            )));
        }
        Ok(())
    }
}

/// Where each header column goes: the index of its required channel in
/// [`REQUIRED`], or `None` for an optional column; `at` makes the error of a
/// column (if one) of the header line.
fn column_slots(
    names: &[String],
    at: &dyn Fn(Option<&str>, String) -> LogError,
) -> Result<Vec<Option<usize>>, LogError> {
    for (i, n) in names.iter().enumerate() {
        if n.is_empty() {
            return Err(at(None, format!("header field {} is empty", i + 1)));
        }
        if names[..i].contains(n) {
            return Err(at(Some(n), "column appears twice".into()));
        }
    }
    let mut slot: Vec<Option<usize>> = vec![None; names.len()];
    for (r, req) in REQUIRED.iter().enumerate() {
        match names.iter().position(|n| n == req) {
            Some(i) => slot[i] = Some(r),
            None => {
                return Err(at(
                    Some(req),
                    "required column is missing from the header".into(),
                ))
            }
        }
    }
    Ok(slot)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "# dca-log v1\n# controller=mpc-eso\n\
t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n\
0.000,0.050000,0.000000,0.0000000,0.0000000,640127.4,1000000.0,0.0\n\
0.001,0.050000,0.012000,0.0000012,0.0000003,641002.1,999987.2,0.1\n\
0.002,0.050000,0.012000,0.0000024,0.0000010,641802.1,999967.2,0.2\n";

    #[test]
    fn reads_the_interface_example() {
        let log = RunLog::parse(GOOD, "good.csv").unwrap();
        assert_eq!(log.len(), 3);
        assert_eq!(log.meta("controller"), Some("mpc-eso"));
        assert_eq!(log.vcmd_mps[1], 0.012);
        assert!((log.dt_s() - 0.001).abs() < 1e-12);
    }

    #[test]
    fn decimation_keeps_every_nth_row_of_every_column() {
        let text = "t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n,z1_m\n\
0.000,0,0,0,0,0,0,0,10\n0.001,1,1,1,1,1,1,1,11\n0.002,2,2,2,2,2,2,2,12\n\
0.003,3,3,3,3,3,3,3,13\n0.004,4,4,4,4,4,4,4,14\n";
        let log = RunLog::parse(text, "x.csv").unwrap();
        let d = log.decimate(2);
        assert_eq!(d.len(), 3);
        assert!((d.dt_s() - 0.002).abs() < 1e-12);
        for col in [
            &d.ref_m,
            &d.vcmd_mps,
            &d.xi_m,
            &d.xo_m,
            &d.p1_pa,
            &d.p2_pa,
            &d.ft_n,
        ] {
            assert_eq!(col, &vec![0.0, 2.0, 4.0]);
        }
        assert_eq!(d.channel("z1_m"), Some(&[10.0, 12.0, 14.0][..]));
        assert_eq!(log.decimate(1), log);
        assert_eq!(log.decimate(0), log);
    }

    #[test]
    fn columns_in_any_order_and_extras_kept() {
        let text = "ft_n,t_s,xo_m,z1_m,ref_m,vcmd_mps,xi_m,p1_pa,p2_pa\n\
1,0.0,0.1,7,0,0,0,0,0\n2,0.5,0.2,8,0,0,0,0,0\n";
        let log = RunLog::parse(text, "x.csv").unwrap();
        assert_eq!(log.ft_n, vec![1.0, 2.0]);
        assert_eq!(log.xo_m, vec![0.1, 0.2]);
        assert_eq!(log.channel("z1_m"), Some(&[7.0, 8.0][..]));
    }

    fn error_of(text: &str) -> LogError {
        RunLog::parse(text, "bad.csv").unwrap_err()
    }

    #[test]
    fn missing_column_names_header_line_and_column() {
        let e = error_of("# dca-log v1\nt_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,ft_n\n0,0,0,0,0,0,0\n");
        assert_eq!(e.line, Some(2));
        assert_eq!(e.column.as_deref(), Some("p2_pa"));
        assert!(
            e.to_string().starts_with("bad.csv:2: column 'p2_pa'"),
            "{e}"
        );
    }

    #[test]
    fn non_numeric_and_nan_name_line_and_column() {
        let bad = GOOD.replace("641002.1", "abc");
        let e = error_of(&bad);
        assert_eq!((e.line, e.column.as_deref()), (Some(5), Some("p1_pa")));
        let nan = GOOD.replace("0.0000012", "NaN");
        let e = error_of(&nan);
        assert_eq!((e.line, e.column.as_deref()), (Some(5), Some("xi_m")));
        assert!(e.message.contains("finite"), "{e}");
    }

    #[test]
    fn non_uniform_and_decreasing_time_are_rejected() {
        let gap = GOOD.replace("0.002,", "0.003,");
        let e = error_of(&gap);
        assert_eq!((e.line, e.column.as_deref()), (Some(6), Some("t_s")));
        assert!(e.message.contains("non-uniform"), "{e}");
        let back = GOOD.replace("0.002,", "0.0005,");
        let e = error_of(&back);
        assert!(e.message.contains("does not increase"), "{e}");
    }

    /// Found by fuzzing: two finite times more than f64::MAX apart made the
    /// first step infinite, after which every later step passed as uniform.
    #[test]
    fn an_infinite_time_step_is_rejected() {
        let e = error_of(
            "t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n\
-1e308,0,0,0,0,0,0,0\n1e308,0,0,0,0,0,0,0\n1.5e308,0,0,0,0,0,0,0\n",
        );
        assert_eq!((e.line, e.column.as_deref()), (Some(3), Some("t_s")), "{e}");
        assert!(e.message.contains("not a finite number"), "{e}");
    }

    /// Spreadsheet programs start a CSV file with a byte-order mark.
    #[test]
    fn a_byte_order_mark_is_skipped() {
        let with_bom = format!("\u{feff}{GOOD}");
        assert_eq!(
            RunLog::parse(&with_bom, "bom.csv"),
            RunLog::parse(GOOD, "good.csv")
        );
        let bare = GOOD.replace("# dca-log v1\n# controller=mpc-eso\n", "\u{feff}");
        let log = RunLog::parse(&bare, "bom.csv").unwrap();
        assert_eq!(log.t_s, [0.0, 0.001, 0.002]);
    }

    /// A step outside a reader's range is refused at the first step, with
    /// the range; a hint at milliseconds when the step / 1000 would do.
    #[test]
    fn a_step_outside_the_readers_range_is_refused() {
        let range = StepRange {
            min_dt_s: 1e-4,
            max_dt_s: 0.02,
            why: "the test",
        };
        assert!(RunLog::parse_with(GOOD, "good.csv", &range).is_ok());
        let ms = GOOD.replace("\n0.001,", "\n1,").replace("\n0.002,", "\n2,");
        let e = RunLog::parse_with(&ms, "ms.csv", &range).unwrap_err();
        assert_eq!((e.line, e.column.as_deref()), (Some(5), Some("t_s")), "{e}");
        assert_eq!(
            e.message,
            "time step 1 s is outside 0.0001 to 0.02 s, the range of the test; t_s is in \
             seconds: if this column is in milliseconds, divide it by 1000 (a step of 0.001 s)"
        );
        // Any reader takes it.
        assert_eq!(RunLog::parse(&ms, "ms.csv").unwrap().dt_s(), 1.0);
        let huge = GOOD
            .replace("\n0.001,", "\n1e303,")
            .replace("\n0.002,", "\n2e303,");
        let e = RunLog::parse_with(&huge, "huge.csv", &range).unwrap_err();
        assert_eq!(
            e.to_string(),
            "huge.csv:5: column 't_s': time step 1e303 s is outside 0.0001 to 0.02 s, the \
             range of the test"
        );
        let tiny = GOOD
            .replace("\n0.001,", "\n1e-300,")
            .replace("\n0.002,", "\n2e-300,");
        let e = RunLog::parse_with(&tiny, "tiny.csv", &range).unwrap_err();
        assert!(
            e.message.starts_with("time step 1e-300 s is outside"),
            "{e}"
        );
        assert!(!e.message.contains("milliseconds"), "{e}");
    }

    #[test]
    fn wrong_field_count_is_rejected() {
        let short = GOOD.replace(",0.2\n", "\n");
        let e = error_of(&short);
        assert_eq!(e.line, Some(6));
        assert!(e.message.contains("fields"), "{e}");
    }

    #[test]
    fn write_then_read_round_trips() {
        let mut log = RunLog::parse(GOOD, "good.csv").unwrap();
        log.extra.insert("z1_m".into(), vec![0.0, 1e-6, 2e-6]);
        let mut buf = Vec::new();
        log.write_to(&mut buf).unwrap();
        let back = RunLog::parse(std::str::from_utf8(&buf).unwrap(), "rt.csv").unwrap();
        assert_eq!(back.t_s, log.t_s);
        assert_eq!(back.xo_m, log.xo_m);
        assert_eq!(back.extra["z1_m"], log.extra["z1_m"]);
        assert_eq!(back.meta("controller"), Some("mpc-eso"));
    }
}

//! Hose test data (docs/model.md section 9): the quasi-static and the dynamic format.
//!
//! Both formats are plain comma-separated text with one header line naming the
//! columns; the columns may come in any order and extra columns are ignored.
//! Blank lines are skipped; a UTF-8 byte-order mark and `\r\n` line ends are
//! accepted. Quoting is not supported (no field of either format needs it).
//!
//! * quasi-static: `section,p_mpa,dpdt_mpa_s,dvdt_mm3_s` (one row per sample);
//! * dynamic: `run,kind,t_s,p_mpa,dpdt_mpa_s,dvdt_mm3_s`, rows of a run
//!   contiguous and in strictly increasing time.
//!
//! Every error names the file, the line (1-based, the header is line 1) and the
//! column, e.g. `data.csv:17: column 'dpdt_mpa_s': 'abc' is not a number`.
//!
//! The project's own sample data (copies of the hose tests of the design
//! reference) are compiled into the library: [`QuasiStaticData::shipped`] and
//! [`DynamicData::shipped`] need no file at run time.

use std::fmt;
use std::path::Path;

/// Source name of the shipped quasi-static data set in error messages and reports.
pub const SHIPPED_QUASISTATIC_NAME: &str = "data/hose-test-quasistatic.csv";
/// Source name of the shipped dynamic data set.
pub const SHIPPED_DYNAMIC_NAME: &str = "data/hose-test-dynamic.csv";

/// The shipped quasi-static hose test (2520 samples), verbatim.
pub const SHIPPED_QUASISTATIC_CSV: &str = include_str!("../../../data/hose-test-quasistatic.csv");
/// The shipped dynamic hose test (3 runs, 28 000 samples at 1 kHz), verbatim.
pub const SHIPPED_DYNAMIC_CSV: &str = include_str!("../../../data/hose-test-dynamic.csv");

/// Column names of the quasi-static format.
pub const QUASISTATIC_COLUMNS: [&str; 4] = ["section", "p_mpa", "dpdt_mpa_s", "dvdt_mm3_s"];
/// Column names of the dynamic format.
pub const DYNAMIC_COLUMNS: [&str; 6] = ["run", "kind", "t_s", "p_mpa", "dpdt_mpa_s", "dvdt_mm3_s"];

/// What went wrong in a data file.
#[derive(Clone, Debug, PartialEq)]
pub enum DataErrorKind {
    /// The file could not be read.
    Io(String),
    /// The file has no header line.
    Empty,
    /// The header lacks a required column.
    MissingColumn {
        /// The required column.
        column: String,
        /// The header line as found.
        header: String,
    },
    /// A column name appears twice in the header.
    DuplicateColumn(String),
    /// A row has a different number of fields than the header.
    ColumnCount {
        /// Fields in the header.
        expected: usize,
        /// Fields in this row.
        found: usize,
    },
    /// A field is not a number.
    NotANumber {
        /// Column name.
        column: String,
        /// The field as found.
        value: String,
    },
    /// A field is a number but not finite (NaN, inf).
    NotFinite {
        /// Column name.
        column: String,
        /// The field as found.
        value: String,
    },
    /// A field that must be a non-negative integer (`section`, `run`) is not.
    NotAnIndex {
        /// Column name.
        column: String,
        /// The field as found.
        value: String,
    },
    /// A required text field is empty.
    EmptyField(String),
    /// The rows of a run are not contiguous.
    SplitRun(u32),
    /// Time does not increase strictly within a run.
    TimeNotIncreasing {
        /// The run.
        run: u32,
        /// Time of the previous row, s.
        previous_s: f64,
        /// Time of this row, s.
        t_s: f64,
    },
    /// The file has a header but no data rows.
    NoRows,
}

/// A data-file error with its position: file name and 1-based line (`None` for
/// whole-file errors such as I/O failures or an empty file).
#[derive(Clone, Debug, PartialEq)]
pub struct DataError {
    /// The file name as given (or the shipped data set's name).
    pub source: String,
    /// 1-based line number (the header is line 1).
    pub line: Option<usize>,
    /// What went wrong.
    pub kind: DataErrorKind,
}

impl fmt::Display for DataError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(f, "{}:{l}: ", self.source)?,
            None => write!(f, "{}: ", self.source)?,
        }
        match &self.kind {
            DataErrorKind::Io(e) => write!(f, "cannot read: {e}"),
            DataErrorKind::Empty => write!(f, "empty file (no header line)"),
            DataErrorKind::MissingColumn { column, header } => {
                write!(f, "header has no column '{column}' (header: '{header}')")
            }
            DataErrorKind::DuplicateColumn(c) => write!(f, "column '{c}' appears twice in the header"),
            DataErrorKind::ColumnCount { expected, found } => write!(
                f,
                "expected {expected} columns (as in the header), found {found}"
            ),
            DataErrorKind::NotANumber { column, value } => {
                write!(f, "column '{column}': '{value}' is not a number")
            }
            DataErrorKind::NotFinite { column, value } => {
                write!(f, "column '{column}': '{value}' is not finite")
            }
            DataErrorKind::NotAnIndex { column, value } => {
                write!(f, "column '{column}': '{value}' is not a non-negative integer")
            }
            DataErrorKind::EmptyField(c) => write!(f, "column '{c}' is empty"),
            DataErrorKind::SplitRun(r) => write!(
                f,
                "run {r} continues after another run (rows of a run must be contiguous)"
            ),
            DataErrorKind::TimeNotIncreasing {
                run,
                previous_s,
                t_s,
            } => write!(
                f,
                "column 't_s': time {t_s} s does not increase (previous row of run {run}: {previous_s} s)"
            ),
            DataErrorKind::NoRows => write!(f, "no data rows after the header"),
        }
    }
}

impl std::error::Error for DataError {}

/// One quasi-static sample (engineering units of the data set).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuasiStaticSample {
    /// Pressure section index (0, 1, 2 for 0.5-1.5, 1.5-2.5, 2.5-3.5 MPa).
    pub section: u32,
    /// Pressure, MPa (gauge).
    pub p_mpa: f64,
    /// Pressure rate, MPa/s.
    pub dpdt_mpa_s: f64,
    /// Hose wall expansion rate (oil compression excluded), mm^3/s.
    pub dvdt_mm3_s: f64,
}

/// A quasi-static hose test.
#[derive(Clone, Debug, PartialEq)]
pub struct QuasiStaticData {
    /// Where the data came from (file name).
    pub source: String,
    /// The samples in file order.
    pub samples: Vec<QuasiStaticSample>,
}

/// One time-series run of a dynamic hose test (engineering units of the data set).
#[derive(Clone, Debug, PartialEq)]
pub struct DynamicRun {
    /// Run index as in the file.
    pub run: u32,
    /// Kind of excitation (`steps`, `fast_ramps`, `sweep`, ...).
    pub kind: String,
    /// Time, s (strictly increasing).
    pub t_s: Vec<f64>,
    /// Pressure, MPa.
    pub p_mpa: Vec<f64>,
    /// Pressure rate, MPa/s.
    pub dpdt_mpa_s: Vec<f64>,
    /// Hose wall expansion rate, mm^3/s.
    pub dvdt_mm3_s: Vec<f64>,
}

impl DynamicRun {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True if the run has no samples (never for a parsed file).
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }
}

/// A dynamic hose test: runs in file order.
#[derive(Clone, Debug, PartialEq)]
pub struct DynamicData {
    /// Where the data came from (file name).
    pub source: String,
    /// The runs in order of appearance.
    pub runs: Vec<DynamicRun>,
}

impl DynamicData {
    /// Total number of samples over all runs.
    pub fn n_samples(&self) -> usize {
        self.runs.iter().map(DynamicRun::len).sum()
    }
}

/// A parsed CSV table: header and data lines with their line numbers.
struct Table<'a> {
    source: &'a str,
    header: Vec<&'a str>,
    header_line: &'a str,
    rows: Vec<(usize, Vec<&'a str>)>,
}

impl<'a> Table<'a> {
    fn parse(text: &'a str, source: &'a str) -> Result<Self, DataError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
            .filter(|(_, l)| !l.trim().is_empty());
        let (_, header_line) = lines.next().ok_or_else(|| DataError {
            source: source.to_string(),
            line: None,
            kind: DataErrorKind::Empty,
        })?;
        let header: Vec<&str> = header_line.split(',').map(str::trim).collect();
        for (i, h) in header.iter().enumerate() {
            if header[..i].contains(h) {
                return Err(DataError {
                    source: source.to_string(),
                    line: Some(1),
                    kind: DataErrorKind::DuplicateColumn(h.to_string()),
                });
            }
        }
        let rows: Vec<(usize, Vec<&str>)> = lines
            .map(|(n, l)| (n, l.split(',').map(str::trim).collect()))
            .collect();
        let t = Self {
            source,
            header,
            header_line,
            rows,
        };
        if t.rows.is_empty() {
            return Err(DataError {
                source: source.to_string(),
                line: None,
                kind: DataErrorKind::NoRows,
            });
        }
        Ok(t)
    }

    fn err(&self, line: usize, kind: DataErrorKind) -> DataError {
        DataError {
            source: self.source.to_string(),
            line: Some(line),
            kind,
        }
    }

    /// Error unless the row has as many fields as the header.
    fn check_count(&self, line: usize, row: &[&str]) -> Result<(), DataError> {
        if row.len() == self.header.len() {
            Ok(())
        } else {
            Err(self.err(
                line,
                DataErrorKind::ColumnCount {
                    expected: self.header.len(),
                    found: row.len(),
                },
            ))
        }
    }

    /// Index of a required column.
    fn column(&self, name: &str) -> Result<usize, DataError> {
        self.header.iter().position(|h| *h == name).ok_or_else(|| {
            self.err(
                1,
                DataErrorKind::MissingColumn {
                    column: name.to_string(),
                    header: self.header_line.to_string(),
                },
            )
        })
    }

    fn number(&self, line: usize, row: &[&str], col: usize) -> Result<f64, DataError> {
        let (name, s) = (self.header[col], row[col]);
        let v: f64 = s.parse().map_err(|_| {
            self.err(
                line,
                DataErrorKind::NotANumber {
                    column: name.to_string(),
                    value: s.to_string(),
                },
            )
        })?;
        if !v.is_finite() {
            return Err(self.err(
                line,
                DataErrorKind::NotFinite {
                    column: name.to_string(),
                    value: s.to_string(),
                },
            ));
        }
        Ok(v)
    }

    fn index(&self, line: usize, row: &[&str], col: usize) -> Result<u32, DataError> {
        let (name, s) = (self.header[col], row[col]);
        s.parse::<u32>().map_err(|_| {
            self.err(
                line,
                DataErrorKind::NotAnIndex {
                    column: name.to_string(),
                    value: s.to_string(),
                },
            )
        })
    }
}

fn read_file(path: &Path) -> Result<(String, String), DataError> {
    let source = path.display().to_string();
    match std::fs::read_to_string(path) {
        Ok(text) => Ok((text, source)),
        Err(e) => Err(DataError {
            source,
            line: None,
            kind: DataErrorKind::Io(e.to_string()),
        }),
    }
}

impl QuasiStaticData {
    /// Parse quasi-static data from text; `source` names it in errors.
    pub fn parse(text: &str, source: &str) -> Result<Self, DataError> {
        let t = Table::parse(text, source)?;
        let c: Vec<usize> = QUASISTATIC_COLUMNS
            .iter()
            .map(|n| t.column(n))
            .collect::<Result<_, _>>()?;
        let samples = t
            .rows
            .iter()
            .map(|(n, r)| {
                t.check_count(*n, r)?;
                Ok(QuasiStaticSample {
                    section: t.index(*n, r, c[0])?,
                    p_mpa: t.number(*n, r, c[1])?,
                    dpdt_mpa_s: t.number(*n, r, c[2])?,
                    dvdt_mm3_s: t.number(*n, r, c[3])?,
                })
            })
            .collect::<Result<Vec<_>, DataError>>()?;
        Ok(Self {
            source: source.to_string(),
            samples,
        })
    }

    /// Load quasi-static data from a file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, DataError> {
        let (text, source) = read_file(path.as_ref())?;
        Self::parse(&text, &source)
    }

    /// The project's sample data (2520 samples), compiled in.
    pub fn shipped() -> Self {
        Self::parse(SHIPPED_QUASISTATIC_CSV, SHIPPED_QUASISTATIC_NAME)
            .expect("the shipped quasi-static data parse (checked by a test)")
    }

    /// The distinct section indices, ascending.
    pub fn sections(&self) -> Vec<u32> {
        let mut s: Vec<u32> = self.samples.iter().map(|s| s.section).collect();
        s.sort_unstable();
        s.dedup();
        s
    }

    /// Inputs [P MPa, dP/dt MPa/s] and outputs dV/dt mm^3/s of the samples with the
    /// given indices.
    pub fn xy(&self, idx: &[usize]) -> (Vec<[f64; 2]>, Vec<f64>) {
        idx.iter()
            .map(|&i| {
                let s = &self.samples[i];
                ([s.p_mpa, s.dpdt_mpa_s], s.dvdt_mm3_s)
            })
            .unzip()
    }

    /// Indices of the samples of one section, in file order.
    pub fn section_indices(&self, section: u32) -> Vec<usize> {
        (0..self.samples.len())
            .filter(|&i| self.samples[i].section == section)
            .collect()
    }
}

impl DynamicData {
    /// Parse dynamic data from text; `source` names it in errors.
    pub fn parse(text: &str, source: &str) -> Result<Self, DataError> {
        let t = Table::parse(text, source)?;
        let c: Vec<usize> = DYNAMIC_COLUMNS
            .iter()
            .map(|n| t.column(n))
            .collect::<Result<_, _>>()?;
        let mut runs: Vec<DynamicRun> = Vec::new();
        for (n, r) in &t.rows {
            let n = *n;
            t.check_count(n, r)?;
            let run = t.index(n, r, c[0])?;
            let kind = r[c[1]];
            if kind.is_empty() {
                return Err(t.err(n, DataErrorKind::EmptyField("kind".to_string())));
            }
            let t_s = t.number(n, r, c[2])?;
            let p = t.number(n, r, c[3])?;
            let dp = t.number(n, r, c[4])?;
            let dv = t.number(n, r, c[5])?;
            let same = runs.last().is_some_and(|last| last.run == run);
            if !same {
                if runs.iter().any(|x| x.run == run) {
                    return Err(t.err(n, DataErrorKind::SplitRun(run)));
                }
                runs.push(DynamicRun {
                    run,
                    kind: kind.to_string(),
                    t_s: Vec::new(),
                    p_mpa: Vec::new(),
                    dpdt_mpa_s: Vec::new(),
                    dvdt_mm3_s: Vec::new(),
                });
            }
            let cur = runs.last_mut().expect("pushed above");
            if let Some(&prev) = cur.t_s.last() {
                if t_s <= prev {
                    return Err(t.err(
                        n,
                        DataErrorKind::TimeNotIncreasing {
                            run,
                            previous_s: prev,
                            t_s,
                        },
                    ));
                }
            }
            cur.t_s.push(t_s);
            cur.p_mpa.push(p);
            cur.dpdt_mpa_s.push(dp);
            cur.dvdt_mm3_s.push(dv);
        }
        Ok(Self {
            source: source.to_string(),
            runs,
        })
    }

    /// Load dynamic data from a file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, DataError> {
        let (text, source) = read_file(path.as_ref())?;
        Self::parse(&text, &source)
    }

    /// The project's sample data (runs `steps`, `fast_ramps`, `sweep`), compiled in.
    pub fn shipped() -> Self {
        Self::parse(SHIPPED_DYNAMIC_CSV, SHIPPED_DYNAMIC_NAME)
            .expect("the shipped dynamic data parse (checked by a test)")
    }
}

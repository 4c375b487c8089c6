//! Hose test data: the shipped sample data and the loaders' error messages.

use host_sim::model::hose::data::{DataErrorKind, DynamicData, QuasiStaticData};

#[test]
fn shipped_quasistatic_data() {
    let d = QuasiStaticData::shipped();
    assert_eq!(d.samples.len(), 2520);
    assert_eq!(d.sections(), vec![0, 1, 2]);
    for s in d.sections() {
        let idx = d.section_indices(s);
        assert_eq!(idx.len(), 840, "section {s}");
        // Each section spans its pressure band (plus noise).
        let lo = 0.5 + f64::from(s);
        for &i in &idx {
            let p = d.samples[i].p_mpa;
            assert!(p > lo - 0.01 && p < lo + 1.01, "section {s}: p = {p}");
        }
    }
    let first = d.samples[0];
    assert_eq!(
        (
            first.section,
            first.p_mpa,
            first.dpdt_mpa_s,
            first.dvdt_mm3_s
        ),
        (0, 0.510215, 0.261283, 48.52386)
    );
}

#[test]
fn shipped_dynamic_data() {
    let d = DynamicData::shipped();
    assert_eq!(d.n_samples(), 28_000);
    let kinds: Vec<(u32, &str, usize)> = d
        .runs
        .iter()
        .map(|r| (r.run, r.kind.as_str(), r.len()))
        .collect();
    assert_eq!(
        kinds,
        vec![
            (0, "steps", 12_000),
            (1, "fast_ramps", 6_000),
            (2, "sweep", 10_000)
        ]
    );
    for r in &d.runs {
        assert!(
            r.t_s.windows(2).all(|w| (w[1] - w[0] - 1e-3).abs() < 1e-9),
            "1 kHz"
        );
    }
}

fn qs_err(text: &str) -> String {
    QuasiStaticData::parse(text, "data.csv")
        .unwrap_err()
        .to_string()
}

fn dyn_err(text: &str) -> String {
    DynamicData::parse(text, "dyn.csv").unwrap_err().to_string()
}

const QS_HEADER: &str = "section,p_mpa,dpdt_mpa_s,dvdt_mm3_s\n";

#[test]
fn quasistatic_errors_name_file_line_and_column() {
    let good = "0,1.0,0.5,10\n";
    // A valid file parses, with or without CRLF, BOM, blank lines, extra columns
    // and another column order.
    let ok = QuasiStaticData::parse(&format!("{QS_HEADER}{good}{good}"), "data.csv").unwrap();
    assert_eq!(ok.samples.len(), 2);
    let ok = QuasiStaticData::parse(
        "\u{feff}note,dvdt_mm3_s,dpdt_mpa_s,p_mpa,section\r\n\r\nx,10,0.5,1.0,2\r\n",
        "data.csv",
    )
    .unwrap();
    assert_eq!(ok.samples[0].section, 2);
    assert_eq!(ok.samples[0].dvdt_mm3_s, 10.0);

    // Not a number: line 3 (header is line 1).
    let text = format!("{QS_HEADER}{good}0,1.0,abc,10\n");
    assert_eq!(
        qs_err(&text),
        "data.csv:3: column 'dpdt_mpa_s': 'abc' is not a number"
    );
    // Non-finite values.
    let text = format!("{QS_HEADER}0,NaN,0.5,10\n");
    assert_eq!(
        qs_err(&text),
        "data.csv:2: column 'p_mpa': 'NaN' is not finite"
    );
    let text = format!("{QS_HEADER}0,1.0,0.5,inf\n");
    assert_eq!(
        qs_err(&text),
        "data.csv:2: column 'dvdt_mm3_s': 'inf' is not finite"
    );
    // Wrong column count.
    let text = format!("{QS_HEADER}{good}{good}0,1.0,0.5\n");
    assert_eq!(
        qs_err(&text),
        "data.csv:4: expected 4 columns (as in the header), found 3"
    );
    // Missing column: names the header line.
    let e = qs_err("section,p_mpa,dvdt_mm3_s\n0,1,2\n");
    assert_eq!(
        e,
        "data.csv:1: header has no column 'dpdt_mpa_s' (header: 'section,p_mpa,dvdt_mm3_s')"
    );
    // Section must be a non-negative integer.
    let text = format!("{QS_HEADER}1.5,1.0,0.5,10\n");
    assert_eq!(
        qs_err(&text),
        "data.csv:2: column 'section': '1.5' is not a non-negative integer"
    );
    // Empty file, header only, duplicate column.
    assert_eq!(qs_err(""), "data.csv: empty file (no header line)");
    assert_eq!(qs_err(QS_HEADER), "data.csv: no data rows after the header");
    assert_eq!(
        qs_err("section,p_mpa,p_mpa,dpdt_mpa_s,dvdt_mm3_s\n"),
        "data.csv:1: column 'p_mpa' appears twice in the header"
    );
    // Blank lines do not shift line numbers.
    let text = format!("{QS_HEADER}\n{good}\n0,x,0.5,10\n");
    assert_eq!(
        qs_err(&text),
        "data.csv:5: column 'p_mpa': 'x' is not a number"
    );
    // The first error in file order wins.
    let text = format!("{QS_HEADER}0,1.0,zz,10\n0,1\n");
    assert!(qs_err(&text).starts_with("data.csv:2:"));
}

#[test]
fn dynamic_errors() {
    let h = "run,kind,t_s,p_mpa,dpdt_mpa_s,dvdt_mm3_s\n";
    let ok = DynamicData::parse(
        &format!("{h}0,steps,0,1,2,3\n0,steps,0.001,1,2,3\n1,sweep,0,1,2,3\n"),
        "dyn.csv",
    )
    .unwrap();
    assert_eq!(ok.runs.len(), 2);
    assert_eq!(ok.runs[1].kind, "sweep");
    assert_eq!(
        dyn_err(&format!("{h}0,steps,0,1,2,3\n0,steps,0,1,2,3\n")),
        "dyn.csv:3: column 't_s': time 0 s does not increase (previous row of run 0: 0 s)"
    );
    assert_eq!(
        dyn_err(&format!(
            "{h}0,steps,0,1,2,3\n1,sweep,0,1,2,3\n0,steps,1,1,2,3\n"
        )),
        "dyn.csv:4: run 0 continues after another run (rows of a run must be contiguous)"
    );
    assert_eq!(
        dyn_err(&format!("{h}0,,0,1,2,3\n")),
        "dyn.csv:2: column 'kind' is empty"
    );
    assert_eq!(
        dyn_err(&format!("{h}-1,steps,0,1,2,3\n")),
        "dyn.csv:2: column 'run': '-1' is not a non-negative integer"
    );
    assert_eq!(
        dyn_err("run,kind,p_mpa,dpdt_mpa_s,dvdt_mm3_s\n0,a,1,2,3\n"),
        "dyn.csv:1: header has no column 't_s' (header: 'run,kind,p_mpa,dpdt_mpa_s,dvdt_mm3_s')"
    );
    assert_eq!(
        dyn_err(&format!("{h}0,steps,0,1,2,3,4\n")),
        "dyn.csv:2: expected 6 columns (as in the header), found 7"
    );
}

#[test]
fn load_from_file_and_missing_file() {
    let dir = std::env::temp_dir().join(format!("grnn-data-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("user.csv");
    std::fs::write(&path, format!("{QS_HEADER}1,2.0,0.25,40\n1,2.1,0.25,41\n")).unwrap();
    let d = QuasiStaticData::load(&path).unwrap();
    assert_eq!(d.samples.len(), 2);
    assert_eq!(d.source, path.display().to_string());
    std::fs::write(&path, format!("{QS_HEADER}1,2.0,0.25,40\n1,2.1,oops,41\n")).unwrap();
    let e = QuasiStaticData::load(&path).unwrap_err();
    assert_eq!(e.line, Some(3));
    assert_eq!(
        e.to_string(),
        format!(
            "{}:3: column 'dpdt_mpa_s': 'oops' is not a number",
            path.display()
        )
    );
    let e = QuasiStaticData::load(dir.join("missing.csv")).unwrap_err();
    assert!(matches!(e.kind, DataErrorKind::Io(_)), "{e}");
    assert!(e.to_string().contains("missing.csv: cannot read"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

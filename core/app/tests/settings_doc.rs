//! docs/firmware.md lists every setting of `PARAMS` with its range and type;
//! the list there must be the table's.

use dca_app::settings::{ParamKind, PARAMS};

/// A bound as a person writes it: plain between 1e-3 and 1e5, else in
/// exponent form.
fn num(v: f64) -> String {
    if v == 0.0 || (1e-3..1e5).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// The table's rows as docs/firmware.md shows them.
fn rows() -> Vec<String> {
    PARAMS
        .iter()
        .map(|p| {
            let kind = match p.kind {
                ParamKind::F64 => "f64",
                ParamKind::F32 => "f32",
                ParamKind::Int => "integer",
                ParamKind::Bool => "flag",
            };
            format!(
                "| `{}` | {} | {} | {kind} |",
                p.name,
                num(p.min),
                num(p.max)
            )
        })
        .collect()
}

#[test]
fn the_manual_lists_every_setting_with_its_range() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/firmware.md");
    let manual = std::fs::read_to_string(path).unwrap();
    let head = "| path | min | max | type |\n|---|---|---|---|\n";
    let start = manual
        .find(head)
        .expect("docs/firmware.md has the settings table")
        + head.len();
    let end = start
        + manual[start..]
            .find("<!-- end of settings table -->")
            .expect("the table's end marker");
    let shown: Vec<&str> = manual[start..end].lines().collect();
    let want = rows();
    if std::env::var_os("DCA_BLESS").is_some() {
        let mut text = manual[..start].to_string();
        text.push_str(&want.join("\n"));
        text.push('\n');
        text.push_str(&manual[end..]);
        std::fs::write(path, text).unwrap();
        return;
    }
    assert_eq!(
        shown, want,
        "update the settings table of docs/firmware.md (DCA_BLESS=1 cargo test -p dca-app --test settings_doc)"
    );
}

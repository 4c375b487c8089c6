//! Tolerance specs: how far a built rig of this class may be from its
//! nominal values, per parameter, with the reason (`sweep --perturb-spec`).
//!
//! A spec is a TOML file with one table per plant parameter key (the keys of
//! [`crate::model::params`], the hose wall's under `[hose.<field>]`), each
//! giving a distribution around the rig's value ([`Spread`]) and a one-line
//! reason:
//!
//! ```toml
//! [ap1_m2]
//! dist = "uniform"      # within +-half_width of the value
//! half_width = 0.01
//! reason = "25 mm bore H8 and 12 mm rod f7: the annulus to 0.5 %"
//! [beta_e_pa]
//! dist = "normal"       # sigma as a fraction, truncated at 3 sigma
//! sigma = 0.15
//! reason = "..."
//! [hose.cs0_m3pp]
//! dist = "lognormal"    # median the value, sigma of its logarithm
//! sigma = 0.25
//! reason = "..."
//! ```
//!
//! Keys not listed are not drawn. Errors name the file, the line and the key
//! ([`FileError`]): an unknown key or field, a missing or unknown `dist`, a
//! missing fraction or one that is not in [0, 1) (for `normal`, its
//! truncation must also stay short of -100 %), a missing or multi-line
//! `reason`.

use std::ops::Range;
use std::path::Path;

use serde::de::{DeserializeSeed, Deserializer};
use serde::Deserialize;
use toml::Spanned;

use crate::io::num::Num;
use crate::model::params::{KeyedTable, ParamKey, Spread, TRUNCATE_SIGMAS};
use crate::sim::config::{self, FileError};

/// One parameter's tolerance.
#[derive(Clone, Debug, PartialEq)]
pub struct Tolerance {
    /// The parameter.
    pub key: &'static ParamKey,
    /// How it is drawn around the rig's value.
    pub spread: Spread,
    /// Why this spread (one line).
    pub reason: String,
}

/// A tolerance spec: the file it came from and its tolerances in file order.
#[derive(Clone, Debug, PartialEq)]
pub struct ToleranceSpec {
    /// The file, as given.
    pub file: String,
    /// One per listed key.
    pub tolerances: Vec<Tolerance>,
}

/// One key's table as written.
#[derive(Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a table with `dist`, `half_width` or `sigma`, and `reason`"
)]
struct RawEntry {
    dist: Option<Spanned<String>>,
    half_width: Option<Spanned<f64>>,
    sigma: Option<Spanned<f64>>,
    reason: Option<Spanned<String>>,
}

/// The spec as read: each key with its table and where the table is.
struct RawSpec {
    entries: Vec<(&'static ParamKey, Spanned<RawEntry>)>,
}

impl<'de> Deserialize<'de> for RawSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let mut entries = Vec::new();
        KeyedTable {
            hose: false,
            expecting: [
                "a table of tolerances by plant parameter",
                "the table [hose] of hose-wall tolerances",
            ],
            out: &mut entries,
        }
        .deserialize(d)?;
        Ok(Self { entries })
    }
}

/// The distributions a spec may name, for messages.
const DISTS: &str = "`uniform` (with `half_width`), `normal` or `lognormal` (with `sigma`)";

/// One key's table checked: its spread and reason, or the error at its line.
fn check_entry(
    key: &'static ParamKey,
    e: &Spanned<RawEntry>,
    text: &str,
    file: &str,
) -> Result<Tolerance, FileError> {
    let err = |span: Range<usize>, message: String| FileError {
        file: file.to_string(),
        line: Some(config::line_of(text, span.start)),
        field: Some(key.name.to_string()),
        message,
    };
    let table = e.span();
    let e = e.get_ref();
    let dist = e
        .dist
        .as_ref()
        .ok_or_else(|| err(table.clone(), format!("missing `dist`: {DISTS}")))?;
    let (name, given, other) = match dist.get_ref().as_str() {
        "uniform" => ("half_width", &e.half_width, &e.sigma),
        "normal" | "lognormal" => ("sigma", &e.sigma, &e.half_width),
        d => {
            return Err(err(
                dist.span(),
                format!("unknown distribution `{d}`, expected {DISTS}"),
            ))
        }
    };
    let d = dist.get_ref().as_str();
    if let Some(o) = other {
        let o_name = if name == "sigma" {
            "half_width"
        } else {
            "sigma"
        };
        return Err(err(
            o.span(),
            format!("`{d}` takes `{name}`, not `{o_name}`"),
        ));
    }
    let f = given.as_ref().ok_or_else(|| {
        err(
            table.clone(),
            format!("missing `{name}` (a fraction of the value) for `{d}`"),
        )
    })?;
    let v = *f.get_ref();
    if !(v.is_finite() && (0.0..1.0).contains(&v)) {
        return Err(err(
            f.span(),
            format!(
                "`{name}` = {}: expected a fraction in [0, 1), e.g. 0.05 for 5 %",
                Num(v)
            ),
        ));
    }
    if d == "normal" && TRUNCATE_SIGMAS * v >= 1.0 {
        return Err(err(
            f.span(),
            format!(
                "`sigma` = {}: truncated at {} sigma the draw reaches -{} % and the value's \
                 sign could flip; `normal` takes sigma below {}, `lognormal` any in [0, 1)",
                Num(v),
                Num(TRUNCATE_SIGMAS),
                Num(TRUNCATE_SIGMAS * v * 100.0),
                Num(1.0 / TRUNCATE_SIGMAS)
            ),
        ));
    }
    let reason = e.reason.as_ref().ok_or_else(|| {
        err(
            table.clone(),
            "missing `reason`: say in one line where this spread comes from".into(),
        )
    })?;
    let r = reason.get_ref().trim();
    if r.is_empty() || r.contains('\n') {
        return Err(err(
            reason.span(),
            "`reason` must be one line of text, not empty".into(),
        ));
    }
    let spread = match d {
        "uniform" => Spread::Uniform { half_width: v },
        "normal" => Spread::Normal { sigma: v },
        _ => Spread::LogNormal { sigma: v },
    };
    Ok(Tolerance {
        key,
        spread,
        reason: r.to_string(),
    })
}

/// A tolerance spec from TOML text; `file` names it in errors.
pub fn spec_str(text: &str, file: &str) -> Result<ToleranceSpec, FileError> {
    let raw: RawSpec = config::parse(text, file)?;
    let tolerances = raw
        .entries
        .iter()
        .map(|(k, e)| check_entry(k, e, text, file))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(ToleranceSpec {
        file: file.to_string(),
        tolerances,
    })
}

/// A tolerance spec from a file (`sweep --perturb-spec FILE`), as [`spec_str`].
pub fn read_spec(path: &Path) -> Result<ToleranceSpec, FileError> {
    spec_str(&config::read(path)?, &path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::params::physical_keys;

    fn err(text: &str) -> String {
        spec_str(text, "t.toml").unwrap_err().to_string()
    }

    #[test]
    fn a_good_spec_reads_in_file_order() {
        let s = spec_str(
            "# a spec\n[m_kg]\ndist = \"normal\"\nsigma = 0.05\nreason = \"weighed\"\n\
             [hose.cs0_m3pp]\ndist = \"lognormal\"\nsigma = 0.25\nreason = \" batches \"\n\
             [ap1_m2]\ndist = \"uniform\"\nhalf_width = 0\nreason = \"machined\"\n",
            "t.toml",
        )
        .unwrap();
        assert_eq!(s.file, "t.toml");
        let got: Vec<(&str, Spread, &str)> = s
            .tolerances
            .iter()
            .map(|t| (t.key.name, t.spread, t.reason.as_str()))
            .collect();
        assert_eq!(
            got,
            [
                ("m_kg", Spread::Normal { sigma: 0.05 }, "weighed"),
                (
                    "hose.cs0_m3pp",
                    Spread::LogNormal { sigma: 0.25 },
                    "batches"
                ),
                ("ap1_m2", Spread::Uniform { half_width: 0.0 }, "machined"),
            ]
        );
        assert!(spec_str("", "e.toml").unwrap().tolerances.is_empty());
    }

    #[test]
    fn bad_specs_name_file_line_and_key() {
        let ok = "dist = \"normal\"\nsigma = 0.1\nreason = \"r\"\n";
        for (text, want) in [
            (
                format!("[mass]\n{ok}"),
                "t.toml:1: field 'mass': unknown field `mass`, expected one of `m_kg`",
            ),
            (
                format!("[m_kg]\n{ok}[hose.m_kg]\n{ok}"),
                "t.toml:5: field 'm_kg': unknown field `m_kg`, expected one of `ce0_m3pp`",
            ),
            (
                "[m_kg]\nsigma = 0.1\nreason = \"r\"\n".into(),
                "t.toml:1: field 'm_kg': missing `dist`: `uniform` (with `half_width`)",
            ),
            (
                "[m_kg]\ndist = \"gauss\"\nsigma = 0.1\nreason = \"r\"\n".into(),
                "t.toml:2: field 'm_kg': unknown distribution `gauss`, expected `uniform`",
            ),
            (
                "\n[beta_e_pa]\ndist = \"normal\"\nsigma = 0.1\n".into(),
                "t.toml:2: field 'beta_e_pa': missing `reason`: say in one line",
            ),
            (
                "[m_kg]\ndist = \"normal\"\nsigma = 0.1\nreason = \"  \"\n".into(),
                "t.toml:4: field 'm_kg': `reason` must be one line of text, not empty",
            ),
            (
                "[m_kg]\ndist = \"normal\"\nsigma = 0.1\nreason = \"\"\"a\nb\"\"\"\n".into(),
                "t.toml:4: field 'm_kg': `reason` must be one line",
            ),
            (
                "[m_kg]\ndist = \"uniform\"\nhalf_width = -0.1\nreason = \"r\"\n".into(),
                "t.toml:3: field 'm_kg': `half_width` = -0.1: expected a fraction in [0, 1)",
            ),
            (
                "[hose.ps_pa]\ndist = \"lognormal\"\nsigma = 1\nreason = \"r\"\n".into(),
                "t.toml:3: field 'hose.ps_pa': `sigma` = 1: expected a fraction in [0, 1)",
            ),
            (
                "[m_kg]\ndist = \"normal\"\nsigma = nan\nreason = \"r\"\n".into(),
                "`sigma` = NaN: expected a fraction",
            ),
            (
                "[m_kg]\ndist = \"normal\"\nsigma = 0.4\nreason = \"r\"\n".into(),
                "t.toml:3: field 'm_kg': `sigma` = 0.4: truncated at 3 sigma the draw reaches \
                 -120 %",
            ),
            (
                "[m_kg]\ndist = \"uniform\"\nsigma = 0.1\nreason = \"r\"\n".into(),
                "t.toml:3: field 'm_kg': `uniform` takes `half_width`, not `sigma`",
            ),
            (
                "[m_kg]\ndist = \"normal\"\nreason = \"r\"\n".into(),
                "t.toml:1: field 'm_kg': missing `sigma` (a fraction of the value) for `normal`",
            ),
            (
                format!("[m_kg]\n{ok}wide = 1\n"),
                "t.toml:5: field 'wide': unknown field `wide`, expected one of `dist`",
            ),
            (
                "m_kg = 0.1\n".into(),
                "t.toml:1: invalid type: floating point",
            ),
            (
                "[m_kg]\ndist = \"normal\"\nsigma = \"5 %\"\n".into(),
                "t.toml:3",
            ),
        ] {
            let e = err(&text);
            assert!(e.contains(want), "{text:?}:\n{e}");
        }
    }

    /// The shipped spec reads, and lists exactly the keys `--perturb F`
    /// draws, each with its reason and a spread of the kind its reason
    /// argues (machined areas within about a percent, the rest wider).
    #[test]
    fn the_shipped_spec_covers_every_physical_key() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/tolerances/dca-rig.toml");
        let s = read_spec(&path).unwrap();
        let mut listed: Vec<&str> = s.tolerances.iter().map(|t| t.key.name).collect();
        let mut physical: Vec<&str> = physical_keys().iter().map(|k| k.name).collect();
        listed.sort_unstable();
        physical.sort_unstable();
        assert_eq!(listed, physical);
        for t in &s.tolerances {
            assert!(t.reason.len() > 20, "{}: {}", t.key.name, t.reason);
            let f = t.spread.fraction();
            assert!(f > 0.0, "{}", t.key.name);
            if ["ap1_m2", "ap2_m2", "aa1_m2", "aa2_m2"].contains(&t.key.name) {
                assert_eq!(t.spread, Spread::Uniform { half_width: 0.01 });
            }
        }
        let beta = s.tolerances.iter().find(|t| t.key.name == "beta_e_pa");
        assert!(beta.unwrap().spread.fraction() >= 0.1);
        let e = read_spec(Path::new("no/such.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("no/such.toml: "), "{e}");
    }
}

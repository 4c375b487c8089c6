//! The layers of host-sim (`src/lib.rs`): every source file belongs to the
//! layer of its top folder,
//!
//! | layer | folders |
//! |---|---|
//! | 0 | `io` |
//! | 1 | `model` |
//! | 2 | `sim` |
//! | 3 | `gap`, `hil`, `studies` |
//! | 4 | `cli` and `main.rs` (the binary) |
//!
//! and may refer only to its own layer or below; and no two modules (source
//! files) refer to each other, directly or through others (no import cycle).
//!
//! A file refers to a module through `use` trees (`crate::`, `super::`,
//! `self::` and paths starting at a child module) and through paths written
//! in the code (`crate::a::b::f()`, `super::stats::median(...)`); the module
//! referred to is the longest prefix of the path that is a source file.
//! Comments, string literals and `#[cfg(test)]` items are not read: unit
//! tests may use test helpers of any module of the crate.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// A module path, e.g. `["gap", "diagnose"]` (empty: the crate root).
type ModPath = Vec<String>;

/// The module path of a source file relative to `src/` (`a/mod.rs` and
/// `a.rs` are both `a`).
fn module_of(rel: &str) -> ModPath {
    let rel = rel.trim_end_matches(".rs");
    let mut parts: Vec<String> = rel.split('/').map(str::to_string).collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// The layer of a source file, from its top folder (`None`: the crate root).
fn layer_of(rel: &str) -> Option<u8> {
    if rel == "main.rs" {
        return Some(4);
    }
    match rel.split('/').next()? {
        "io" => Some(0),
        "model" => Some(1),
        "sim" => Some(2),
        "gap" | "hil" | "studies" => Some(3),
        "cli" => Some(4),
        _ => None,
    }
}

/// The text with comments and string and char literals blanked out, and
/// `#[cfg(test)]` items removed.
fn code_only(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
            i += 2;
            while i + 1 < b.len() && !(b[i] == b'*' && b[i + 1] == b'/') {
                i += 1;
            }
            i += 2;
        } else if b[i] == b'"' {
            // Raw strings (r"..", r#".."#) have no escapes; ordinary ones may.
            let raw = i > 0 && (b[i - 1] == b'r' || b[i - 1] == b'#');
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' && !raw {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
            out.push_str("\"\"");
        } else if b[i] == b'\'' && b.get(i + 2) == Some(&b'\'') {
            i += 3;
            out.push_str("' '");
        } else if b[i] == b'\'' && b.get(i + 1) == Some(&b'\\') {
            i += 2;
            while i < b.len() && b[i] != b'\'' {
                i += 1;
            }
            i += 1;
            out.push_str("' '");
        } else {
            let c = text[i..].chars().next().expect("in bounds");
            out.push(c);
            i += c.len_utf8();
        }
    }
    strip_cfg_test(&out)
}

/// Remove every item after a `#[cfg(test)]` attribute (up to its closing
/// brace, or its semicolon).
fn strip_cfg_test(code: &str) -> String {
    let mut out = String::new();
    let mut rest = code;
    while let Some(at) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..at]);
        let item = &rest[at..];
        let mut depth = 0usize;
        let mut end = item.len();
        for (i, c) in item.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = i + 1;
                        break;
                    }
                }
                ';' if depth == 0 => {
                    end = i + 1;
                    break;
                }
                _ => {}
            }
        }
        rest = &item[end..];
    }
    out.push_str(rest);
    out
}

/// The paths of a `use` tree (`a::{b, c::{d as e, self}}` -> `a::b`, `a::c::d`, `a::c`).
fn use_paths(tree: &str) -> Vec<String> {
    // Drop the renames (`as NAME`), keep what follows the name (`,`, `}`).
    let mut flat = String::new();
    let mut words = tree.split_whitespace();
    while let Some(w) = words.next() {
        if w == "as" {
            let alias = words.next().unwrap_or("");
            flat.push_str(alias.trim_start_matches(|c: char| c.is_alphanumeric() || c == '_'));
        } else {
            flat.push_str(w);
        }
    }
    let mut out = Vec::new();
    expand("", &flat, &mut out);
    out
}

fn expand(prefix: &str, tree: &str, out: &mut Vec<String>) {
    let join = |p: &str, s: &str| {
        if p.is_empty() {
            s.to_string()
        } else if s == "self" {
            p.to_string()
        } else {
            format!("{p}::{s}")
        }
    };
    match tree.find('{') {
        None => out.push(join(prefix, tree.trim_end_matches("::*"))),
        Some(open) => {
            let head = tree[..open].trim_end_matches("::");
            let inner = &tree[open + 1..tree.len() - 1];
            let p = join(prefix, head);
            let p = if head.is_empty() {
                prefix.to_string()
            } else {
                p
            };
            let mut depth = 0;
            let mut start = 0;
            for (i, c) in inner.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        if !inner[start..i].is_empty() {
                            expand(&p, &inner[start..i], out);
                        }
                        start = i + 1;
                    }
                    _ => {}
                }
            }
            if !inner[start..].is_empty() {
                expand(&p, &inner[start..], out);
            }
        }
    }
}

/// Every path a file refers to: the paths of its `use` trees and the paths
/// written in its code (`a::b` and longer, starting with a lowercase name).
fn referenced_paths(code: &str) -> Vec<String> {
    let mut paths = Vec::new();
    let word = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let bytes = code.as_bytes();
    // `use` declarations (also `pub use`, `pub(crate) use`).
    let mut from = 0;
    while let Some(at) = code[from..].find("use ") {
        let at = from + at;
        if at == 0 || !word(bytes[at - 1]) {
            if let Some(end) = code[at..].find(';') {
                paths.extend(use_paths(&code[at + 4..at + end]));
            }
        }
        from = at + 4;
    }
    // Paths in the code.
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i].is_ascii_lowercase()
            && (i == 0 || !(word(bytes[i - 1]) || bytes[i - 1] == b':'))
        {
            let mut end = i;
            while end < bytes.len() && (word(bytes[end]) || bytes[end] == b':') {
                end += 1;
            }
            let path = code[i..end].trim_end_matches(':');
            if path.contains("::") {
                paths.push(path.to_string());
            }
            i = end;
        } else {
            i += 1;
        }
    }
    paths
}

/// The module a path refers to from module `here` (the longest prefix that is
/// a known module), or `None` for paths outside the crate.
fn resolve(path: &str, here: &ModPath, modules: &BTreeSet<ModPath>) -> Option<ModPath> {
    let segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
    let first = *segs.first()?;
    let (mut abs, rest): (ModPath, &[&str]) = match first {
        "crate" => (Vec::new(), &segs[1..]),
        "self" => (here.clone(), &segs[1..]),
        "super" => {
            let mut p = here.clone();
            let mut n = 0;
            while segs.get(n) == Some(&"super") {
                p.pop();
                n += 1;
            }
            (p, &segs[n..])
        }
        // A path from a child module (2018 paths: `use child::Item;`).
        child => {
            let mut p = here.clone();
            p.push(child.to_string());
            if !modules.contains(&p) {
                return None;
            }
            (here.clone(), &segs[..])
        }
    };
    let mut best = abs.clone();
    for s in rest {
        abs.push(s.to_string());
        if modules.contains(&abs) {
            best = abs.clone();
        } else {
            break;
        }
    }
    Some(best)
}

/// The layer and cycle problems of a crate given as (path under `src/`, text).
fn problems(files: &[(String, String)]) -> Vec<String> {
    let modules: BTreeSet<ModPath> = files.iter().map(|(p, _)| module_of(p)).collect();
    let layer_of_mod: BTreeMap<ModPath, Option<u8>> = files
        .iter()
        .map(|(p, _)| (module_of(p), layer_of(p)))
        .collect();
    let mut out = Vec::new();
    let mut edges: BTreeMap<ModPath, BTreeSet<ModPath>> = BTreeMap::new();
    for (rel, text) in files {
        // `super` is the parent of the file's module (of `a` in `a/mod.rs`
        // and of `a::b` in `a/b.rs`).
        let here = module_of(rel);
        let Some(layer) = layer_of(rel) else {
            continue;
        };
        // Each module referred to, with the first path that does.
        let mut targets: BTreeMap<ModPath, String> = BTreeMap::new();
        for path in referenced_paths(&code_only(text)) {
            if let Some(target) = resolve(&path, &here, &modules) {
                if target != here && !target.is_empty() {
                    targets.entry(target).or_insert(path);
                }
            }
        }
        for (target, path) in targets {
            let to_layer = layer_of_mod.get(&target).copied().flatten();
            if let Some(to) = to_layer {
                if to > layer {
                    out.push(format!(
                        "src/{rel} (layer {layer}) refers to {} (layer {to}) with `{path}`",
                        target.join("::")
                    ));
                }
            }
            edges.entry(here.clone()).or_default().insert(target);
        }
    }
    out.extend(cycles(&edges).into_iter().map(|c| {
        format!(
            "import cycle among {}",
            c.iter()
                .map(|m| m.join("::"))
                .collect::<Vec<_>>()
                .join(", ")
        )
    }));
    out
}

/// The cycles of a directed graph: the strongly connected components of more
/// than one node (Tarjan), each sorted.
fn cycles(edges: &BTreeMap<ModPath, BTreeSet<ModPath>>) -> Vec<Vec<ModPath>> {
    struct Tarjan<'a> {
        edges: &'a BTreeMap<ModPath, BTreeSet<ModPath>>,
        index: BTreeMap<ModPath, usize>,
        low: BTreeMap<ModPath, usize>,
        stack: Vec<ModPath>,
        on_stack: BTreeSet<ModPath>,
        next: usize,
        sccs: Vec<Vec<ModPath>>,
    }
    impl Tarjan<'_> {
        fn visit(&mut self, v: &ModPath) {
            self.index.insert(v.clone(), self.next);
            self.low.insert(v.clone(), self.next);
            self.next += 1;
            self.stack.push(v.clone());
            self.on_stack.insert(v.clone());
            for w in self.edges.get(v).into_iter().flatten() {
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let lw = self.low[w];
                    let lv = self.low.get_mut(v).expect("visited");
                    *lv = (*lv).min(lw);
                } else if self.on_stack.contains(w) {
                    let iw = self.index[w];
                    let lv = self.low.get_mut(v).expect("visited");
                    *lv = (*lv).min(iw);
                }
            }
            if self.low[v] == self.index[v] {
                let mut scc = Vec::new();
                loop {
                    let w = self.stack.pop().expect("on the stack");
                    self.on_stack.remove(&w);
                    let done = &w == v;
                    scc.push(w);
                    if done {
                        break;
                    }
                }
                if scc.len() > 1 {
                    scc.sort();
                    self.sccs.push(scc);
                }
            }
        }
    }
    let mut t = Tarjan {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        next: 0,
        sccs: Vec::new(),
    };
    for v in edges.keys() {
        if !t.index.contains_key(v) {
            t.visit(v);
        }
    }
    t.sccs
}

/// Every `.rs` file under `dir`, as (path relative to `root`, text).
fn sources(root: &Path, dir: &Path, out: &mut Vec<(String, String)>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            sources(root, &p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            let rel = p
                .strip_prefix(root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            out.push((rel, std::fs::read_to_string(&p).unwrap()));
        }
    }
}

#[test]
fn every_module_imports_from_its_own_layer_or_below_without_cycles() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&root, &root, &mut files);
    assert!(files.len() > 40, "{} source files", files.len());
    for (rel, _) in &files {
        assert!(
            layer_of(rel).is_some() || rel == "lib.rs",
            "src/{rel} is in no layer: put it in io, model, sim, gap, hil, studies or cli"
        );
    }
    let p = problems(&files);
    assert!(p.is_empty(), "{}", p.join("\n"));
}

fn file(path: &str, text: &str) -> (String, String) {
    (path.to_string(), text.to_string())
}

#[test]
fn an_upward_import_is_found_in_every_spelling() {
    let base = [
        file("io/mod.rs", "pub mod log;"),
        file("io/log.rs", "pub struct Log;"),
        file("sim/mod.rs", "pub struct Trace;"),
    ];
    for body in [
        "use crate::sim::Trace;",
        "use crate::{io::log::Log, sim::{self, Trace}};",
        "pub(crate) use crate::sim::Trace as T;",
        "fn f() -> crate::sim::Trace { todo!() }",
        "use super::super::sim::Trace;",
    ] {
        let mut files = base.to_vec();
        files.push(file("io/bad.rs", body));
        let p = problems(&files);
        assert!(
            p.len() == 1 && p[0].contains("src/io/bad.rs (layer 0) refers to sim (layer 2)"),
            "{body}: {p:?}"
        );
    }
    // Comments, strings and unit tests do not count.
    let mut files = base.to_vec();
    files.push(file(
        "io/ok.rs",
        "//! See [`crate::sim::Trace`].\nconst S: &str = \"crate::sim::Trace\";\n\
         #[cfg(test)]\nmod tests {\n    use crate::sim::Trace;\n}\n",
    ));
    assert_eq!(problems(&files), Vec::<String>::new());
}

#[test]
fn an_import_cycle_is_found() {
    let files = [
        file("gap/mod.rs", "pub mod a;\npub mod b;\npub mod c;"),
        file("gap/a.rs", "use super::b::B;\npub struct A;"),
        file("gap/b.rs", "use super::c::C;\npub struct B;"),
        file("gap/c.rs", "pub struct C;\nfn f() { let _ = super::a::A; }"),
    ];
    let p = problems(&files);
    assert_eq!(p, ["import cycle among gap::a, gap::b, gap::c"], "{p:?}");
    // Parent and child modules count like any two: a child using its
    // parent's items and the parent using the child's is a cycle.
    let files = [
        file("sim/mod.rs", "pub mod run;\nuse run::go;\npub struct Spec;"),
        file("sim/run.rs", "use crate::sim::Spec;\npub fn go() {}"),
    ];
    assert_eq!(problems(&files), ["import cycle among sim, sim::run"]);
}

//! The module layering of `thicket-core` (docs/architecture.md), checked from the sources: a
//! module may use only modules on a lower layer. A reference counts when code outside tests
//! names another top-level module through `crate::` (a `use` line or a path in code, including
//! `use crate::{a, b}` groups); comments, doc links and test code (`#[cfg(test)]` items and
//! the files they declare) may point anywhere, as tests load samples and render to check.
//!
//! `scripts/check.sh` runs this first (`cargo test -p thicket-core --test layers`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every top-level module of the crate and its layer, lowest first. Modules on one layer are
/// independent of each other. Keep in step with the table in docs/architecture.md.
const LAYERS: &[(&str, u32)] = &[
    // Plain data and maths with no crate dependency.
    ("mesh", 0),
    ("krs", 0),
    ("budget", 0),
    // The octree (colours come from `mesh`'s sRGB helpers).
    ("svo", 1),
    // Algorithms over plain octrees and meshes.
    ("deform", 2),
    ("voxelize", 2),
    ("enhance", 2),
    // Skeletons, clips, rigs and per-node skinning (a `deform::NodeDeform`).
    ("skin", 3),
    // The renderers' knobs (one of them is a skinning stretch strategy).
    ("quality", 4),
    // The document.
    ("scene", 5),
    // The CPU renderers: Document → image.
    ("render", 6),
    // Files ↔ documents (the impostor exporter renders).
    ("io", 7),
    // Harnesses and tools on top of everything.
    ("measure", 8),
    ("sculpt", 8),
];

/// One reference from a lower or equal layer to a module it may not use.
#[derive(Debug, PartialEq, Eq)]
struct Violation {
    file: String,
    line: usize,
    from: String,
    to: String,
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let layer = |m: &str| layer_of(m).map_or_else(|| "?".to_owned(), |l| l.to_string());
        write!(
            f,
            "{}:{}: `{}` (layer {}) uses `{}` (layer {})",
            self.file,
            self.line,
            self.from,
            layer(&self.from),
            self.to,
            layer(&self.to)
        )
    }
}

fn layer_of(module: &str) -> Option<u32> {
    LAYERS.iter().find(|(m, _)| *m == module).map(|&(_, l)| l)
}

/// `source` with comments, string and char literals blanked (same length, newlines kept), so
/// neither `crate::` inside them nor their braces count.
fn blank_comments_and_literals(source: &str) -> String {
    let b: Vec<char> = source.chars().collect();
    let mut out = String::with_capacity(source.len());
    let mut i = 0;
    let blank = |c: char| if c == '\n' { '\n' } else { ' ' };
    while i < b.len() {
        let c = b[i];
        let next = b.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < b.len() && b[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == '/' && b.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if b[i] == '*' && b.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(blank(b[i]));
                    i += 1;
                }
            }
        } else if c == 'r' && (next == Some('"') || next == Some('#')) && !ident_char_before(&b, i)
        {
            // Raw string r"…" / r#"…"#.
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            j += 1;
            loop {
                match b.get(j) {
                    None => break,
                    Some('"') if (1..=hashes).all(|k| b.get(j + k) == Some(&'#')) => {
                        j += 1 + hashes;
                        break;
                    }
                    _ => j += 1,
                }
            }
            for &ch in &b[i..j.min(b.len())] {
                out.push(blank(ch));
            }
            i = j;
        } else if c == '"' {
            out.push(' ');
            i += 1;
            while i < b.len() && b[i] != '"' {
                if b[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                if i < b.len() {
                    out.push(blank(b[i]));
                    i += 1;
                }
            }
            if i < b.len() {
                out.push(' ');
                i += 1;
            }
        } else if c == '\'' {
            // A char literal ('x', '\n', '\u{7f}'); otherwise a lifetime or label.
            let end = if next == Some('\\') {
                (i + 2..b.len().min(i + 12)).find(|&k| b[k] == '\'')
            } else if b.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            if let Some(end) = end {
                for _ in i..=end {
                    out.push(' ');
                }
                i = end + 1;
            } else {
                out.push(c);
                i += 1;
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

fn ident_char_before(b: &[char], i: usize) -> bool {
    i > 0 && (b[i - 1].is_alphanumeric() || b[i - 1] == '_')
}

/// `code` (already blanked) with every `#[cfg(test)]` item blanked: from the attribute to the
/// end of the item's braces, or to its `;` when it has none (`mod tests;`).
fn blank_test_items(code: &str) -> String {
    const ATTR: &str = "#[cfg(test)]";
    let mut out: Vec<char> = code.chars().collect();
    let text: String = out.iter().collect();
    let mut search = 0;
    while let Some(found) = text[search..].find(ATTR) {
        let start = search + found;
        // Byte offsets equal char offsets only for ASCII; map through char indices.
        let start_ch = text[..start].chars().count();
        let mut j = start_ch + ATTR.chars().count();
        let mut depth = 0usize;
        let mut opened = false;
        while j < out.len() {
            match out[j] {
                '{' => {
                    depth += 1;
                    opened = true;
                }
                '}' => {
                    depth = depth.saturating_sub(1);
                    if opened && depth == 0 {
                        j += 1;
                        break;
                    }
                }
                ';' if !opened => {
                    j += 1;
                    break;
                }
                _ => {}
            }
            j += 1;
        }
        let end = j.min(out.len());
        for ch in &mut out[start_ch..end] {
            if *ch != '\n' {
                *ch = ' ';
            }
        }
        search = start + ATTR.len();
    }
    out.into_iter().collect()
}

/// The top-level modules named through `crate::` in `code` (blanked), with 1-based lines.
fn crate_references(code: &str) -> Vec<(usize, String)> {
    let mut refs = Vec::new();
    let mut rest = code;
    let mut offset = 0;
    while let Some(p) = rest.find("crate::") {
        let at = offset + p;
        let before_ok = at == 0 || {
            let c = code[..at].chars().next_back().unwrap_or(' ');
            !(c.is_alphanumeric() || c == '_' || c == '$')
        };
        let after = &code[at + "crate::".len()..];
        let line = code[..at].matches('\n').count() + 1;
        if before_ok {
            if let Some(group) = after.strip_prefix('{') {
                // `crate::{a::x, b}`: the first name of every top-level entry.
                let mut depth = 0usize;
                let mut entry_start = true;
                let mut local_line = line;
                for (k, ch) in group.char_indices() {
                    match ch {
                        '{' => depth += 1,
                        '}' if depth == 0 => break,
                        '}' => depth -= 1,
                        ',' if depth == 0 => entry_start = true,
                        '\n' => local_line += 1,
                        c if entry_start && (c.is_alphanumeric() || c == '_') => {
                            let name: String = group[k..]
                                .chars()
                                .take_while(|c| c.is_alphanumeric() || *c == '_')
                                .collect();
                            refs.push((local_line, name));
                            entry_start = false;
                        }
                        _ => {}
                    }
                }
            } else {
                let name: String = after
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    refs.push((line, name));
                }
            }
        }
        offset = at + "crate::".len();
        rest = &code[offset..];
    }
    refs
}

/// The violations in one non-test source file of top-level module `module`.
fn check_source(file: &str, module: &str, source: &str) -> Vec<Violation> {
    let code = blank_test_items(&blank_comments_and_literals(source));
    let Some(own) = layer_of(module) else {
        return vec![Violation {
            file: file.to_owned(),
            line: 1,
            from: module.to_owned(),
            to: "(a module missing from LAYERS)".to_owned(),
        }];
    };
    crate_references(&code)
        .into_iter()
        .filter(|(_, to)| to != module)
        .filter(|(_, to)| layer_of(to).is_none_or(|l| l >= own))
        .map(|(line, to)| Violation {
            file: file.to_owned(),
            line,
            from: module.to_owned(),
            to,
        })
        .collect()
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .expect("the source folder is readable")
        .map(|e| e.expect("a readable entry").path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// Files declared as `#[cfg(test)] mod x;` (with or without `#[path]`), and the files those
/// declare in turn: test code as a whole.
fn test_files(files: &[PathBuf]) -> BTreeSet<PathBuf> {
    let mut tests = BTreeSet::new();
    for f in files {
        let source = std::fs::read_to_string(f).expect("a readable source file");
        let lines: Vec<&str> = source.lines().collect();
        for (i, l) in lines.iter().enumerate() {
            if l.trim() != "#[cfg(test)]" {
                continue;
            }
            let mut j = i + 1;
            let mut path_attr = None;
            while j < lines.len() && lines[j].trim().starts_with("#[") {
                let t = lines[j].trim();
                if let Some(p) = t.strip_prefix("#[path = \"") {
                    path_attr = p.strip_suffix("\"]").map(str::to_owned);
                }
                j += 1;
            }
            let Some(decl) = lines.get(j) else { continue };
            let decl = decl.trim();
            let decl = decl
                .strip_prefix("pub(crate) ")
                .or_else(|| decl.strip_prefix("pub(super) "))
                .or_else(|| decl.strip_prefix("pub "))
                .unwrap_or(decl);
            let Some(name) = decl.strip_prefix("mod ").and_then(|d| d.strip_suffix(';')) else {
                continue;
            };
            let dir = f.parent().expect("a file has a folder");
            let stem = f.file_stem().and_then(|s| s.to_str()).unwrap_or("");
            let owner_dir = if matches!(stem, "mod" | "lib") {
                dir.to_path_buf()
            } else {
                dir.join(stem)
            };
            match path_attr {
                Some(p) => {
                    tests.insert(dir.join(p));
                }
                None => {
                    tests.insert(owner_dir.join(format!("{name}.rs")));
                    tests.insert(owner_dir.join(name).join("mod.rs"));
                }
            }
        }
    }
    // What a test file declares in turn lives in its folder (`x/tests.rs` → `x/tests/…`,
    // `x/tests/mod.rs` → `x/tests/…`): test code too.
    let folders: Vec<PathBuf> = tests
        .iter()
        .map(|t| match t.file_name().and_then(|n| n.to_str()) {
            Some("mod.rs") => t.parent().map_or_else(|| t.clone(), Path::to_path_buf),
            _ => t.with_extension(""),
        })
        .collect();
    for f in files {
        if folders.iter().any(|d| f.starts_with(d)) {
            tests.insert(f.clone());
        }
    }
    tests
}

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn every_top_level_module_has_a_layer() {
    let lib = std::fs::read_to_string(src_dir().join("lib.rs")).expect("lib.rs");
    let declared: BTreeSet<&str> = lib
        .lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .filter_map(|l| l.strip_suffix(';'))
        .collect();
    let listed: BTreeSet<&str> = LAYERS.iter().map(|&(m, _)| m).collect();
    assert_eq!(
        declared, listed,
        "lib.rs's modules and LAYERS differ: give a new module its layer here and in \
         docs/architecture.md"
    );
}

#[test]
fn lower_modules_never_use_higher_ones() {
    let src = src_dir();
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let tests = test_files(&files);
    let mut violations = Vec::new();
    let mut edges: BTreeMap<(String, String), usize> = BTreeMap::new();
    let mut checked = 0;
    for f in &files {
        let rel = f.strip_prefix(&src).expect("under src");
        let Some(first) = rel.components().next() else {
            continue;
        };
        let first = first.as_os_str().to_string_lossy();
        if rel.as_os_str() == "lib.rs" || tests.contains(f) {
            continue;
        }
        let module = first.strip_suffix(".rs").unwrap_or(&first).to_owned();
        let source = std::fs::read_to_string(f).expect("a readable source file");
        let shown = format!("core/src/{}", rel.display());
        checked += 1;
        let code = blank_test_items(&blank_comments_and_literals(&source));
        for (_, to) in crate_references(&code) {
            if to != module {
                *edges.entry((module.clone(), to)).or_default() += 1;
            }
        }
        violations.extend(check_source(&shown, &module, &source));
    }
    let mut uses: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    for (from, to) in edges.keys() {
        uses.entry(from).or_default().insert(to);
    }
    println!(
        "layers: {checked} non-test files, {} module pairs",
        edges.len()
    );
    for (from, to) in &uses {
        let to: Vec<&str> = to.iter().copied().collect();
        println!(
            "  {from} (layer {}) uses {}",
            layer_of(from).unwrap_or(99),
            to.join(", ")
        );
    }
    assert!(
        checked > 50,
        "only {checked} files found under {}",
        src.display()
    );
    assert!(
        violations.is_empty(),
        "{} upward references (the layer order is in docs/architecture.md; move the shared \
         item down, or the user up):\n{}",
        violations.len(),
        violations
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join("\n")
    );
    println!("layers: no module uses a module on its own or a higher layer");
}

// The checker itself must catch what it is for, and ignore what it allows.

#[test]
fn an_upward_use_is_caught_in_every_form() {
    let cases = [
        "use crate::render::Quality;\n",
        "use crate::{mesh::MeshModel, render::Projection};\n",
        "fn f() -> crate::render::Projection { todo!() }\n",
        "pub struct S {\n    pub a: crate::io::GltfView,\n}\n",
        "use crate::{\n    svo::Svo,\n    measure::image,\n};\n",
    ];
    for src in cases {
        let v = check_source("x.rs", "scene", src);
        assert_eq!(v.len(), 1, "{src:?} gave {v:?}");
        assert!(
            matches!(v[0].to.as_str(), "render" | "io" | "measure"),
            "{v:?}"
        );
    }
    // The line is reported.
    let v = check_source(
        "x.rs",
        "scene",
        "use crate::svo::Svo;\n\nuse crate::render::Camera;\n",
    );
    assert_eq!(v[0].line, 3);
    // Same layer is refused too (siblings are independent).
    assert_eq!(
        check_source("x.rs", "voxelize", "use crate::enhance::X;").len(),
        1
    );
    // A module not in the table is refused.
    assert_eq!(check_source("x.rs", "newthing", "").len(), 1);
}

#[test]
fn downward_uses_comments_strings_and_tests_pass() {
    let src = r#"
//! See [`crate::render::Camera`] for how this is drawn.
use crate::svo::Svo; // not crate::io
/// Links to [`crate::measure`] are documentation, not dependencies.
const S: &str = "crate::io::project";
const C: char = '{';
fn f<'a>(x: &'a str) -> &'a str { x }
#[cfg(test)]
mod tests {
    use crate::io::project::load;
    fn g() { let _ = "}"; crate::render::render_document(); }
}
#[cfg(test)]
mod more_tests;
fn after_tests() -> crate::skin::Rig { todo!() }
"#;
    assert_eq!(check_source("x.rs", "scene", src), Vec::new());
    // What follows a test module is checked again.
    let bad = format!("{src}\nuse crate::io::IoError;\n");
    let v = check_source("x.rs", "scene", &bad);
    assert_eq!(v.len(), 1, "{v:?}");
    assert_eq!(v[0].to, "io");
}

//! The module layering of `thicket-core` (docs/architecture.md), checked from the sources: a
//! module may use only modules on a lower layer. A reference counts when code outside tests
//! names another top-level module through `crate::` (a `use` line or a path in code, including
//! `use crate::{a, b}` groups); comments, doc links and test code (`#[cfg(test)]` items and
//! the files they declare) may point anywhere, as tests load samples and render to check.
//!
//! `scripts/check.sh` runs this first (`cargo test -p thicket-core --test layers`).

mod scan;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use scan::{
    blank_comments_and_literals, blank_test_items, crate_references, rust_files, test_files,
};

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

//! The app's module layering (docs/architecture.md), checked from the sources as core's
//! `layers` test does: the editor knows nothing of the UI or the renderers, the preview layer
//! nothing of the UI, and no two files of `ui` use each other in a circle (directly or
//! through others). Comments, doc links and test code do not count.

#[path = "../../core/tests/scan/mod.rs"]
mod scan;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use scan::{blank_comments_and_literals, blank_test_items, references, rust_files, test_files};

/// Top-level modules of the app crate and the app modules each must never use.
const FORBIDDEN: &[(&str, &[&str])] = &[
    (
        "editor",
        &["ui", "preview", "gpu", "cli", "bench", "tradeoff"],
    ),
    ("gpu", &["ui", "preview", "editor", "cli"]),
    ("preview", &["ui", "cli"]),
];

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// Every non-test source file under `src/`, with its code blanked of comments, literals and
/// test items, and its path relative to `src/`.
fn sources() -> Vec<(PathBuf, String)> {
    let src = src_dir();
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let tests = test_files(&files);
    files
        .into_iter()
        .filter(|f| !tests.contains(f))
        .map(|f| {
            let source = std::fs::read_to_string(&f).expect("a readable source file");
            let code = blank_test_items(&blank_comments_and_literals(&source));
            (f.strip_prefix(&src).expect("under src").to_path_buf(), code)
        })
        .collect()
}

/// The top-level module a file belongs to.
fn top_module(rel: &Path) -> String {
    let first = rel
        .components()
        .next()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .unwrap_or_default();
    first.strip_suffix(".rs").unwrap_or(&first).to_owned()
}

#[test]
fn the_editor_and_the_preview_layer_never_use_the_ui() {
    let mut violations = Vec::new();
    let mut checked = BTreeSet::new();
    for (rel, code) in sources() {
        let module = top_module(&rel);
        let Some((_, forbidden)) = FORBIDDEN.iter().find(|(m, _)| *m == module) else {
            continue;
        };
        checked.insert(module.clone());
        for (line, to) in references(&code, "crate::") {
            if forbidden.contains(&to.as_str()) {
                violations.push(format!("{}:{line}: `{module}` uses `{to}`", rel.display()));
            }
        }
    }
    assert_eq!(
        checked.len(),
        FORBIDDEN.len(),
        "every listed module has sources: {checked:?}"
    );
    assert!(violations.is_empty(), "{}", violations.join("\n"));
}

/// A circle in `graph`, if there is one (depth-first search from every node).
fn find_circle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        n: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|p| p == n) {
            let mut circle = path[at..].to_vec();
            circle.push(n.to_owned());
            return Some(circle);
        }
        if done.contains(n) {
            return None;
        }
        path.push(n.to_owned());
        for m in graph.get(n).into_iter().flatten() {
            if let Some(c) = visit(m, graph, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(n.to_owned());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|n| visit(n, graph, &mut Vec::new(), &mut done))
}

#[test]
fn no_two_ui_files_use_each_other_in_a_circle() {
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (rel, code) in sources() {
        if top_module(&rel) != "ui" {
            continue;
        }
        // A file directly in ui/ names its siblings as `super::x`; any file may write
        // `crate::ui::x`.
        let name = rel
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let direct = rel.parent() == Some(Path::new("ui")) && name != "mod";
        let mut to: Vec<(usize, String)> = references(&code, "crate::ui::");
        if direct {
            to.extend(references(&code, "super::"));
        }
        let entry = graph.entry(name.clone()).or_default();
        entry.extend(to.into_iter().map(|(_, m)| m).filter(|m| *m != name));
    }
    assert!(
        graph.len() > 20 && graph.values().map(BTreeSet::len).sum::<usize>() > 20,
        "the scan found the ui files and their uses: {graph:?}"
    );
    // The scan finds a circle when there is one.
    let mut planted = graph.clone();
    planted
        .entry("projector".to_owned())
        .or_default()
        .insert("view".to_owned());
    assert!(
        find_circle(&planted).is_some(),
        "a planted circle through the view is found"
    );
    assert_eq!(find_circle(&graph), None);
}

//! Reading Rust sources for the layering tests (core's `layers`, the app's `ui_layers`):
//! comments, literals and test items blanked, and the modules a file names through a path
//! prefix.

#![allow(
    dead_code,
    reason = "each test crate that includes this uses a part of it"
)]

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// `source` with comments, string and char literals blanked (same length, newlines kept), so
/// neither `crate::` inside them nor their braces count.
pub fn blank_comments_and_literals(source: &str) -> String {
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
pub fn blank_test_items(code: &str) -> String {
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
pub fn crate_references(code: &str) -> Vec<(usize, String)> {
    references(code, "crate::")
}

/// The modules named right after `prefix` (`crate::`, `super::`, `crate::ui::`) in `code`
/// (blanked), with 1-based lines; a group `prefix{a::x, b}` names each entry's first module.
pub fn references(code: &str, prefix: &str) -> Vec<(usize, String)> {
    let mut refs = Vec::new();
    let mut rest = code;
    let mut offset = 0;
    while let Some(p) = rest.find(prefix) {
        let at = offset + p;
        let before_ok = at == 0 || {
            let c = code[..at].chars().next_back().unwrap_or(' ');
            !(c.is_alphanumeric() || c == '_' || c == '$')
        };
        let after = &code[at + prefix.len()..];
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
        offset = at + prefix.len();
        rest = &code[offset..];
    }
    refs
}

pub fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
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
pub fn test_files(files: &[PathBuf]) -> BTreeSet<PathBuf> {
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

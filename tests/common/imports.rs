//! The imports between the modules of a Rust source tree, read as code
//! (tests/layering.rs, tests/method_recipe.rs): the paths into the crate a
//! file writes (`use crate::…`, `super::…`, `self::…`, `crate::…` anywhere,
//! braces expanded), comments and string literals left out, each resolved
//! to the module (file) it lands in and marked when only test code writes
//! it; a path into a module's own ancestors or descendants does not count.
//! Needs `mod source` (common/source.rs) beside it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use super::source::{self, code_only, is_ident, skip_ws};

/// A module as a path from the root (`[]` is `crate`).
pub type Module = Vec<String>;

pub fn name(m: &[String]) -> String {
    std::iter::once("crate").chain(m.iter().map(String::as_str)).collect::<Vec<_>>().join("::")
}

/// Every `.rs` file of `dir` but the binary's, as (module, file).
fn modules(root: &Path, dir: &Path, out: &mut BTreeMap<Module, PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            modules(root, &p, out);
            continue;
        }
        if p.extension().is_none_or(|e| e != "rs") || p == root.join("main.rs") {
            continue;
        }
        let rel = p.strip_prefix(root).unwrap().with_extension("");
        let mut m: Module = rel.iter().map(|c| c.to_string_lossy().into_owned()).collect();
        if m.last().is_some_and(|l| l == "mod" || l == "lib") {
            m.pop();
        }
        out.insert(m, p);
    }
}

fn ident(b: &[u8], i: usize) -> Option<(String, usize)> {
    let i = skip_ws(b, i);
    let n = b[i..].iter().take_while(|&&c| is_ident(c)).count();
    (n > 0).then(|| (String::from_utf8_lossy(&b[i..i + n]).into_owned(), i + n))
}

/// The paths of a use tree starting at `i` after `prefix::` (a name, a
/// `{…}` group of trees, or `*`), each pushed to `out`; returns the end.
fn use_tree(b: &[u8], mut i: usize, prefix: &[String], out: &mut Vec<Vec<String>>) -> usize {
    i = skip_ws(b, i);
    if b.get(i) == Some(&b'{') {
        i += 1;
        loop {
            i = skip_ws(b, i);
            match b.get(i) {
                None => return i,
                Some(b'}') => return i + 1,
                Some(b',') => i += 1,
                _ => {
                    let before = i;
                    i = use_tree(b, i, prefix, out);
                    if i == before {
                        i += 1;
                    }
                }
            }
        }
    }
    let mut path = prefix.to_vec();
    while let Some((id, j)) = ident(b, i) {
        if id == "as" {
            break;
        }
        path.push(id);
        i = skip_ws(b, j);
        if b[i..].starts_with(b"::") {
            i += 2;
            let k = skip_ws(b, i);
            if b.get(k) == Some(&b'{') {
                return use_tree(b, k, &path, out);
            }
        } else {
            break;
        }
    }
    if path.len() > prefix.len() && path.last().is_some_and(|l| l != "self") {
        out.push(path);
    } else if path.last().is_some_and(|l| l == "self") {
        path.pop();
        out.push(path);
    }
    i
}

/// A path into the crate as written at a line, from inside the inline
/// modules `inline` of the file.
struct Written {
    line: usize,
    inline: Vec<String>,
    path: Vec<String>,
}

/// Every path into the crate (`crate::`, `super::`, `self::`) a file writes.
fn paths(code: &[u8]) -> Vec<Written> {
    let mut out = Vec::new();
    let mut line = 1;
    // Inline modules open at a brace depth: (name, depth).
    let (mut inline, mut depth): (Vec<(String, usize)>, usize) = (Vec::new(), 0);
    let mut i = 0;
    while i < code.len() {
        let c = code[i];
        match c {
            b'\n' => line += 1,
            b'{' => depth += 1,
            b'}' => {
                depth = depth.saturating_sub(1);
                while inline.last().is_some_and(|(_, d)| *d > depth) {
                    inline.pop();
                }
            }
            _ => {}
        }
        let word_start = is_ident(c) && (i == 0 || !is_ident(code[i - 1]));
        if !word_start {
            i += 1;
            continue;
        }
        let (word, end) = ident(code, i).unwrap();
        if word == "mod" {
            if let Some((m, j)) = ident(code, end) {
                let k = skip_ws(code, j);
                if code.get(k) == Some(&b'{') {
                    inline.push((m, depth + 1));
                }
            }
        }
        let preceded_by_path = i >= 2 && &code[i - 2..i] == b"::";
        if matches!(word.as_str(), "crate" | "super" | "self") && !preceded_by_path && code[end..].starts_with(b"::") {
            let mut found = Vec::new();
            let stop = use_tree(code, end + 2, std::slice::from_ref(&word), &mut found);
            for p in found {
                out.push(Written { line, inline: inline.iter().map(|(n, _)| n.clone()).collect(), path: p });
            }
            // Count the lines the tree spanned; braces inside it are balanced.
            line += code[end..stop].iter().filter(|&&c| c == b'\n').count();
            i = stop;
            continue;
        }
        i = end;
    }
    out
}

/// The module (a file) a path written in module `cur` lands in: the
/// longest known prefix.
fn resolve(known: &BTreeMap<Module, PathBuf>, cur: &[String], path: &[String]) -> Option<Module> {
    let (mut base, mut rest): (Vec<String>, &[String]) = match path[0].as_str() {
        "crate" => (Vec::new(), &path[1..]),
        "self" => (cur.to_vec(), &path[1..]),
        _ => (cur.to_vec(), path),
    };
    while rest.first().is_some_and(|s| s == "super") {
        base.pop();
        rest = &rest[1..];
    }
    let mut best = None;
    for k in 0..=rest.len() {
        let mut m = base.clone();
        m.extend(rest[..k].iter().cloned());
        if known.contains_key(&m) {
            best = Some(m);
        }
    }
    best.or_else(|| {
        // From inside an inline module of a file: the file's own module.
        let mut b = base;
        while !b.is_empty() && !known.contains_key(&b) {
            b.pop();
        }
        Some(b)
    })
}

/// One import: from a module to another, where, and whether in test code.
pub struct Edge {
    pub from: Module,
    pub to: Module,
    pub at: String,
    pub test: bool,
}

/// Every import between modules of the tree at `root`.
pub fn imports(root: &Path) -> (BTreeMap<Module, PathBuf>, Vec<Edge>) {
    let mut known = BTreeMap::new();
    modules(root, root, &mut known);
    let mut edges = Vec::new();
    for (m, file) in &known {
        let src = std::fs::read_to_string(file).unwrap();
        let code = code_only(&src);
        let outside_tests: BTreeSet<(usize, Vec<String>)> =
            paths(&source::without_test_items(&code)).into_iter().map(|w| (w.line, w.path)).collect();
        for w in paths(&code) {
            let mut cur = m.clone();
            cur.extend(w.inline.iter().cloned());
            let Some(t) = resolve(&known, &cur, &w.path) else { continue };
            if t.starts_with(m) || m.starts_with(&t) {
                continue;
            }
            let test = !outside_tests.contains(&(w.line, w.path.clone()));
            edges.push(Edge { from: m.clone(), to: t, at: format!("{}:{}", file.display(), w.line), test });
        }
    }
    (known, edges)
}

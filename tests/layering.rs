//! The layers of `src/` (issue 36): no module imports one above it, and no
//! modules import each other around a loop. No GPU.
//!
//! The order is declared once, in docs/architecture.md's ```layers block:
//! one line per scope, `scope: a, b < c < d` (lowest first; `crate` is the
//! library's root). Every module of a declared scope must be named on its
//! line, and a module may import only from modules of its scope on a lower
//! level (not from its own level, not from above). Imports are the paths
//! into the crate a file writes (`use crate::…`, `super::…`, `self::…`,
//! `crate::…` anywhere, braces expanded), comments and string literals left
//! out, `#[cfg(test)]` modules included; a path into a module's own
//! ancestors or descendants does not count. Where two modules meet under an
//! undeclared scope (e.g. two files of `src/mesh/`), only loops are refused.
//! `src/main.rs`, the binary, is another crate above them all.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

#[path = "common/source.rs"]
mod source;
#[path = "common/imports.rs"]
mod imports;
use imports::{imports, name, Edge, Module};

/// The declared layers: scope -> (module -> level).
fn declared(doc: &str) -> BTreeMap<Module, BTreeMap<String, usize>> {
    let start = doc.find("```layers\n").expect("docs/architecture.md has no ```layers block") + "```layers\n".len();
    let end = start + doc[start..].find("```").expect("the ```layers block is not closed");
    let mut scopes = BTreeMap::new();
    for l in doc[start..end].lines().filter(|l| !l.trim().is_empty()) {
        let (scope, order) = l.split_once(':').unwrap_or_else(|| panic!("layers line without 'scope:': {l}"));
        let scope: Module = scope.trim().split("::").filter(|s| *s != "crate").map(String::from).collect();
        let mut levels = BTreeMap::new();
        for (k, level) in order.split('<').enumerate() {
            for m in level.split(',').map(str::trim).filter(|m| !m.is_empty()) {
                assert!(levels.insert(m.to_string(), k).is_none(), "layers: {m} named twice under {}", name(&scope));
            }
        }
        assert!(scopes.insert(scope.clone(), levels).is_none(), "layers: {} declared twice", name(&scope));
    }
    scopes
}

/// Problems with the layers of the tree at `root` under the order `doc`
/// declares: undeclared or missing modules, upward imports, loops.
fn problems(root: &Path, doc: &str, known_loops: &[&str]) -> Vec<String> {
    let (known, edges) = imports(root);
    let scopes = declared(doc);
    let mut out = Vec::new();
    // Each declared scope names exactly its children.
    for (scope, levels) in &scopes {
        let children: BTreeSet<String> =
            known.keys().filter(|m| m.len() > scope.len() && m.starts_with(scope)).map(|m| m[scope.len()].clone()).collect();
        for c in &children {
            if !levels.contains_key(c) {
                out.push(format!("{}::{c} is not in the layers of {} (docs/architecture.md)", name(scope), name(scope)));
            }
        }
        for c in levels.keys() {
            if !children.contains(c) {
                out.push(format!("the layers of {} name {c}, which is not a module", name(scope)));
            }
        }
    }
    for Edge { from, to, at, .. } in &edges {
        let common = from.iter().zip(to).take_while(|(a, b)| a == b).count();
        let scope = &from[..common];
        let Some(levels) = scopes.get(scope) else { continue };
        let (a, b) = (&from[common], &to[common]);
        if let (Some(la), Some(lb)) = (levels.get(a), levels.get(b)) {
            if la <= lb {
                let how = if la == lb { "on its own level" } else { "above it" };
                out.push(format!("{at}: {} imports {}, {how} in the layers of {}", name(from), name(to), name(scope)));
            }
        }
    }
    let loops: Vec<String> =
        cycles(&known, &edges).iter().map(|c| c.iter().map(|m| name(m)).collect::<Vec<_>>().join(" <-> ")).collect();
    for l in &loops {
        if !known_loops.contains(&l.as_str()) {
            out.push(format!("import loop: {l}"));
        }
    }
    for l in known_loops {
        if !loops.iter().any(|f| f == l) {
            out.push(format!("the known loop {l} is gone or changed: update KNOWN_LOOPS"));
        }
    }
    out
}

/// Loops between modules that were there when this check came (issue 36)
/// and are still to be untangled; the list may only shrink. (Empty: the
/// mesh readers' split into tets, `cells` <-> `tetrahedralize` <->
/// `higher_order`, `polyhedron`, `repair`, is untangled, `cells` and
/// `tet_builder` below the splitters, `tetrahedralize` on top.)
const KNOWN_LOOPS: &[&str] = &[];

/// Strongly connected components of more than one module (Tarjan), test
/// code left out (a unit test may use what lists the module under test).
fn cycles(known: &BTreeMap<Module, PathBuf>, edges: &[Edge]) -> Vec<Vec<Module>> {
    let ids: BTreeMap<&Module, usize> = known.keys().enumerate().map(|(i, m)| (m, i)).collect();
    let names: Vec<&Module> = known.keys().collect();
    let mut adj = vec![BTreeSet::new(); ids.len()];
    for e in edges.iter().filter(|e| !e.test) {
        adj[ids[&e.from]].insert(ids[&e.to]);
    }
    struct T<'a> {
        adj: &'a [BTreeSet<usize>],
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        stack: Vec<usize>,
        on: Vec<bool>,
        next: usize,
        out: Vec<Vec<usize>>,
    }
    fn visit(t: &mut T, v: usize) {
        t.index[v] = Some(t.next);
        t.low[v] = t.next;
        t.next += 1;
        t.stack.push(v);
        t.on[v] = true;
        for &w in t.adj[v].clone().iter() {
            match t.index[w] {
                None => {
                    visit(t, w);
                    t.low[v] = t.low[v].min(t.low[w]);
                }
                Some(iw) if t.on[w] => t.low[v] = t.low[v].min(iw),
                _ => {}
            }
        }
        if Some(t.low[v]) == t.index[v] {
            let mut c = Vec::new();
            loop {
                let w = t.stack.pop().unwrap();
                t.on[w] = false;
                c.push(w);
                if w == v {
                    break;
                }
            }
            if c.len() > 1 {
                t.out.push(c);
            }
        }
    }
    let n = ids.len();
    let mut t = T { adj: &adj, index: vec![None; n], low: vec![0; n], stack: Vec::new(), on: vec![false; n], next: 0, out: Vec::new() };
    for v in 0..n {
        if t.index[v].is_none() {
            visit(&mut t, v);
        }
    }
    t.out.into_iter().map(|c| {
        let mut c: Vec<Module> = c.into_iter().map(|i| names[i].clone()).collect();
        c.sort();
        c
    }).collect()
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn no_module_imports_one_above_it_and_no_loops() {
    let doc = std::fs::read_to_string(repo().join("docs/architecture.md")).unwrap();
    let (known, edges) = imports(&repo().join("src"));
    let found = problems(&repo().join("src"), &doc, KNOWN_LOOPS);
    if std::env::var("LAYERS_DEBUG").is_ok() {
        for e in &edges {
            eprintln!("{}: {} -> {}{}", e.at, name(&e.from), name(&e.to), if e.test { " (test)" } else { "" });
        }
    }
    assert!(
        found.is_empty(),
        "the layers of src/ (docs/architecture.md, ```layers) are broken:\n  {}",
        found.join("\n  ")
    );
    eprintln!("{} modules, {} imports between them: layers kept, no loops", known.len(), edges.len());
}

/// The check can fail: an upward import, an import on the same level, a
/// loop inside an undeclared scope, an undeclared module, each named.
#[test]
fn the_check_names_what_breaks_the_layers() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    let write = |p: &str, s: &str| {
        let p = src.join(p);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, s).unwrap();
    };
    write("lib.rs", "pub mod low; pub mod high; pub mod peer;\n");
    write("low/mod.rs", "pub mod a; pub mod b;\n");
    write("low/a.rs", "use super::b::X; // crate::high in a comment is no import\n");
    write("low/b.rs", "pub struct X; const S: &str = \"crate::high::Y\"; use super::a;\n");
    write("high.rs", "use crate::low::{a, b::{X}};\n");
    write("peer.rs", "");
    let doc = "```layers\ncrate: low < high, peer\n```\n";
    let found = problems(src, doc, &[]);
    assert_eq!(found, ["import loop: crate::low::a <-> crate::low::b"], "{found:#?}");

    write("low/b.rs", "pub struct X;\nfn f() { crate::high::g() }\n");
    write("peer.rs", "#[cfg(test)]\nmod tests {\n    use super::super::high::Z;\n}\n");
    write("new.rs", "");
    let found = problems(src, doc, &[]);
    let p = src.display();
    assert_eq!(
        found,
        [
            "crate::new is not in the layers of crate (docs/architecture.md)".to_string(),
            format!("{p}/low/b.rs:2: crate::low::b imports crate::high, above it in the layers of crate"),
            format!("{p}/peer.rs:3: crate::peer imports crate::high, on its own level in the layers of crate"),
            "import loop: crate::high <-> crate::low::a <-> crate::low::b".to_string(),
        ],
        "{found:#?}"
    );
}

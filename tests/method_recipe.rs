//! Adding a method is its family's module, its shaders and two lines
//! (issue 36, point 6; docs/architecture.md, "Adding a method"): a family
//! of methods — a directory or file under `src/algo/` that defines a
//! `pub const METHOD: MethodInfo` — is named by no other Rust code but
//! `src/algo/mod.rs` (its `mod` line) and `src/algo/registry.rs` (its
//! `METHOD` lines), and its shaders (`shaders/<family>/`) are compiled and
//! included by that family alone. So a new method touches its own files
//! and those two lines, nothing of the harness, of another family or of
//! the shared kits (`tet_mesh`, `adaptive`, `common/*.glsl`), which a
//! family imports and never the other way. No GPU.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

#[path = "common/source.rs"]
mod source;
#[path = "common/imports.rs"]
mod imports;
use imports::{imports, name, Edge};

/// The modules that may name every family: `src/algo/mod.rs` (its `mod`
/// line) and `src/algo/registry.rs` (its `METHOD` lines).
const REGISTRATION: &[&[&str]] = &[&["algo"], &["algo", "registry"]];

/// A source file: its path relative to the repository (`/`-separated) and text.
struct File {
    path: String,
    text: String,
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read_tree(root: &Path, dir: &str, out: &mut Vec<File>) {
    let mut entries: Vec<_> = std::fs::read_dir(root.join(dir)).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for p in entries {
        let rel = p.strip_prefix(root).unwrap().to_string_lossy().replace('\\', "/");
        if p.is_dir() {
            read_tree(root, &rel, out);
        } else {
            out.push(File { path: rel, text: std::fs::read_to_string(&p).unwrap() });
        }
    }
}

/// The family a path under `src/algo/` or `shaders/` belongs to: its first
/// component there, without `.rs`.
fn family_of(path: &str) -> Option<&str> {
    let rest = path.strip_prefix("src/algo/").or_else(|| path.strip_prefix("shaders/"))?;
    let first = rest.split('/').next()?;
    Some(first.strip_suffix(".rs").unwrap_or(first))
}

/// The families: where a `pub const METHOD: MethodInfo` is defined.
fn families(files: &[File]) -> BTreeSet<String> {
    files
        .iter()
        .filter(|f| f.path.starts_with("src/algo/") && f.path.ends_with(".rs"))
        .filter(|f| {
            let code = source::code_only(&f.text);
            String::from_utf8_lossy(&code).contains("pub const METHOD: MethodInfo")
        })
        .filter_map(|f| family_of(&f.path).map(str::to_string))
        .collect()
}

/// Whether a line of Rust holds a string literal that is the path of a
/// shader under `shaders/<family>/` (not a data file of the same folder
/// name, e.g. `"terrain/….npz"`).
fn names_shader(line: &str, family: &str) -> bool {
    let literal = format!("\"{family}/");
    line.match_indices(literal.as_str()).any(|(i, _)| {
        let rest = &line[i + 1..];
        let path = rest.split('"').next().unwrap_or("");
        SHADER_EXTENSIONS.iter().any(|e| path.ends_with(e))
    })
}

/// What the files under `shaders/` end in.
const SHADER_EXTENSIONS: &[&str] = &[".vert", ".frag", ".geom", ".comp", ".tesc", ".tese", ".glsl"];

/// Whether `module` is one of [`REGISTRATION`].
fn registers(module: &[String]) -> bool {
    REGISTRATION.iter().any(|r| r.iter().eq(module.iter()))
}

/// The module a `src/` file is (`src/algo/mod.rs`: `algo`).
fn module_of(path: &str) -> Vec<String> {
    let rel = path.strip_prefix("src/").unwrap_or(path).strip_suffix(".rs").unwrap_or(path);
    rel.split('/').filter(|c| *c != "mod").map(String::from).collect()
}

/// Every place where code outside a family names it, in the tree at `root`
/// (its `src/` and `shaders/`). Module paths are read as tests/layering.rs
/// reads them (common/imports.rs: `use` trees with braces, `super::`,
/// `crate::` anywhere), test code left out; shader paths as string literals.
fn problems(root: &Path) -> Vec<String> {
    let mut files = Vec::new();
    read_tree(root, "src", &mut files);
    read_tree(root, "shaders", &mut files);
    let families = families(&files);
    let mut out = Vec::new();
    if families.is_empty() {
        out.push("no family of methods found under src/algo/".to_string());
    }
    let (_, edges) = imports(&root.join("src"));
    for family in &families {
        let module = ["algo".to_string(), family.clone()];
        for Edge { from, to, at, test } in &edges {
            if !test && to.starts_with(&module) && !from.starts_with(&module) && !registers(from) {
                out.push(format!("{at}: {} names the module of family `{family}` (only its own files, src/algo/mod.rs and registry.rs may)", name(from)));
            }
        }
        for f in files.iter().filter(|f| family_of(&f.path) != Some(family.as_str())) {
            if f.path.ends_with(".rs") && !registers(&module_of(&f.path)) && f.text.lines().any(|l| names_shader(l.split("//").next().unwrap_or(""), family)) {
                out.push(format!("{} names a shader of family `{family}`", f.path));
            }
            if f.path.starts_with("shaders/") && f.text.lines().any(|l| l.trim_start().starts_with("#include") && l.contains(&format!("\"{family}/"))) {
                out.push(format!("{} includes a shader of family `{family}`", f.path));
            }
        }
    }
    out
}

#[test]
fn a_family_of_methods_is_named_only_by_its_own_files_and_its_registration() {
    let root = repo();
    let mut files = Vec::new();
    read_tree(&root, "src", &mut files);
    let families = families(&files);
    // The families today (a new one joins this list by its METHOD alone).
    for f in ["cell_projection", "raycast", "terrain", "tet_raycast"] {
        assert!(families.contains(f), "family {f} not found: {families:?}");
    }
    let found = problems(&root);
    assert!(found.is_empty(), "a family of methods is named outside its own files:\n  {}", found.join("\n  "));
}

#[test]
fn the_check_finds_a_family_named_by_the_harness_another_family_or_a_kit() {
    let dir = tempfile::tempdir().unwrap();
    let tree = [
        ("src/algo/mod.rs", "pub mod fam_a; pub mod fam_b; pub mod kit; pub mod registry;"),
        ("src/algo/registry.rs", "use super::fam_a; fn m() { super::fam_a::METHOD; }"),
        ("src/algo/fam_a/mod.rs", "pub const METHOD: MethodInfo = X; fn k() { key(\"fam_a/x.comp\"); }"),
        ("src/algo/fam_b.rs", "pub const METHOD: MethodInfo = X;\n// super::fam_a in a comment is fine\nuse super::fam_a::Kit;"),
        ("src/algo/kit/mod.rs", "pub mod deep; fn f() { super::fam_b::g(); }"),
        ("src/algo/kit/deep.rs", "fn f() { super::super::fam_b::g(); }"),
        ("src/harness/run.rs", "fn f() { let k = \"fam_a/x.comp\"; let d = \"fam_b/data.npz\"; crate::algo::fam_b::h(); }\n#[cfg(test)]\nmod t { use crate::algo::fam_a; }"),
        ("src/harness/suite.rs", "use crate::algo::{kit, fam_a::{Thing}};"),
        ("shaders/fam_b/y.comp", "#include \"fam_a/shared.glsl\"\n#include \"common/z.glsl\""),
        ("shaders/fam_a/x.comp", "#include \"fam_a/shared.glsl\""),
    ];
    for (path, text) in tree {
        let p = dir.path().join(path);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    let found = problems(dir.path());
    let expect = [
        "crate::algo::fam_b names the module of family `fam_a`",
        "crate::algo::kit names the module of family `fam_b`",
        "crate::algo::kit::deep names the module of family `fam_b`",
        "crate::harness::run names the module of family `fam_b`",
        "crate::harness::suite names the module of family `fam_a`",
        "src/harness/run.rs names a shader of family `fam_a`",
        "shaders/fam_b/y.comp includes a shader of family `fam_a`",
    ];
    for e in expect {
        assert!(found.iter().any(|p| p.contains(e)), "not found: {e}\nfound: {found:#?}");
    }
    assert_eq!(found.len(), expect.len(), "{found:#?}");
}

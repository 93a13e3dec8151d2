//! docs/architecture.md's "Layout" names every module under `src/` (every
//! `.rs` file and every directory) and nothing that is gone; the entries
//! beside `src/` exist. No GPU.
//!
//! The layout is a nested Markdown list: an item is `- `NAME` — what it
//! is` (or several names, `- `a.rs`, `b.rs` — ...`), two spaces of indent
//! per level, a directory's name ending in `/` and its entries nested under
//! it; lines that do not start an item continue the one above.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every path the layout names: (`src/...` entries, entries beside `src/`).
fn layout_entries(doc: &str) -> (BTreeSet<String>, Vec<String>) {
    let mut lines = doc.lines().skip_while(|l| l.trim_end() != "## Layout");
    assert!(lines.next().is_some(), "docs/architecture.md has no '## Layout' section");
    let mut src = BTreeSet::new();
    let mut beside = Vec::new();
    // Items with their continuation lines joined: (line number, indent, text).
    let mut items: Vec<(usize, usize, String)> = Vec::new();
    let mut open = false;
    for (n, line) in lines.take_while(|l| !l.starts_with("## ")).enumerate() {
        let indent = line.len() - line.trim_start_matches(' ').len();
        if let Some(item) = line[indent..].strip_prefix("- ") {
            items.push((n + 1, indent, item.to_string()));
            open = true;
        } else if line.trim().is_empty() {
            open = false;
        } else if open {
            let last = items.last_mut().unwrap();
            last.2 = format!("{} {}", last.2, line.trim());
        }
    }
    // The directory each open level names ("src/", "src/vk/", ...).
    let mut dirs: Vec<String> = Vec::new();
    for (n, indent, item) in items {
        assert!(indent % 2 == 0, "Layout line {n}: an indent of {indent} spaces is not a whole level: {item}");
        let depth = indent / 2;
        assert!(depth <= dirs.len(), "Layout line {n}: nested under no directory: {item}");
        dirs.truncate(depth);
        let head = item.split(" — ").next().unwrap();
        let names: Vec<&str> = head.split('`').skip(1).step_by(2).collect();
        assert!(!names.is_empty(), "Layout line {n}: the item names no `path`: {item}");
        let parent = dirs.last().cloned().unwrap_or_default();
        for name in &names {
            let path = format!("{parent}{name}");
            if depth == 0 && path != "src/" {
                beside.push(path);
            } else if path != "src/" {
                assert!(src.insert(path.clone()), "the layout names {path} twice");
            }
        }
        if let [name] = names[..] {
            if name.ends_with('/') {
                dirs.push(format!("{parent}{name}"));
            }
        }
    }
    (src, beside)
}

/// Every `.rs` file and directory under `src/`, as `src/a/b.rs`, `src/a/`.
fn tree(dir: &Path, rel: &str, out: &mut BTreeSet<String>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name().into_string().unwrap();
        let path = entry.path();
        if path.is_dir() {
            let sub = format!("{rel}{name}/");
            out.insert(sub.clone());
            tree(&path, &sub, out);
        } else if name.ends_with(".rs") {
            out.insert(format!("{rel}{name}"));
        }
    }
}

#[test]
fn the_layout_names_every_module_under_src_and_nothing_that_is_gone() {
    let doc = std::fs::read_to_string(root().join("docs/architecture.md")).unwrap();
    let (documented, beside) = layout_entries(&doc);
    let mut actual = BTreeSet::new();
    tree(&root().join("src"), "src/", &mut actual);
    assert!(actual.len() > 100 && documented.len() > 100, "{} in the tree, {} in the layout", actual.len(), documented.len());
    let missing: Vec<&String> = actual.difference(&documented).collect();
    let stale: Vec<&String> = documented.difference(&actual).collect();
    let mut problems = Vec::new();
    for p in &missing {
        problems.push(format!("  missing: {p} is in the tree but not in the layout: add a line for it"));
    }
    for p in &stale {
        problems.push(format!("  stale:   {p} is named in the layout but is not in src/: remove it or correct its path"));
    }
    assert!(problems.is_empty(), "docs/architecture.md, \"## Layout\", and src/ disagree:\n{}", problems.join("\n"));
    for p in &beside {
        assert!(root().join(p).exists(), "docs/architecture.md's layout names {p} beside src/, which does not exist");
    }
}

#[test]
fn the_layout_parser_nests_names_under_their_directories() {
    let doc = "# A\n\n## Layout\n\nintro with `src/nope.rs`\n\n- `src/`\n  - `lib.rs` — the lib\n    continued `src/not.rs`\n  - `vk/` — layer\n    - `mod.rs` — x\n    - `a.rs`, `b.rs`,\n      `c.rs` — three\n  - `main.rs`\n\nBeside:\n\n- `docs/` — d\n\n## Next\n\n- `src/after.rs`\n";
    let (src, beside) = layout_entries(doc);
    let want: BTreeSet<String> =
        ["src/lib.rs", "src/vk/", "src/vk/mod.rs", "src/vk/a.rs", "src/vk/b.rs", "src/vk/c.rs", "src/main.rs"].map(String::from).into();
    assert_eq!(src, want);
    assert_eq!(beside, ["docs/"]);
}

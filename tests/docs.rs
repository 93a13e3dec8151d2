//! The documents a new user reads keep their shape: README.md is a front
//! door of at most 150 lines whose methods table names every registered
//! method (with its family) and nothing else, and every relative link in
//! the Markdown pages (README, docs/, results/ and data/ READMEs, the
//! history) reaches a file that exists and, with `#anchor`, a heading of
//! it. No GPU.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use volbench::algo::registry;

const README_MAX_LINES: usize = 150;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// The cells of a Markdown table row (`| a | b |` → `["a", "b"]`).
fn cells(line: &str) -> Vec<String> {
    let inner = line.trim().trim_start_matches('|').trim_end_matches('|');
    inner.split('|').map(|c| c.trim().to_string()).collect()
}

/// The lines of the section under `## title`, up to the next `## `.
fn section<'a>(text: &'a str, title: &str) -> Vec<&'a str> {
    let mut lines = text.lines().skip_while(|l| l.trim_end() != format!("## {title}"));
    assert!(lines.next().is_some(), "no section '## {title}'");
    lines.take_while(|l| !l.starts_with("## ")).collect()
}

#[test]
fn readme_is_at_most_150_lines() {
    let n = read("README.md").lines().count();
    assert!(
        n <= README_MAX_LINES,
        "README.md has {n} lines, more than {README_MAX_LINES}: it is the front door (what volbench is, the two \
         commands, the methods, where results go, the current figures); move detail to docs/ and history to \
         results/HISTORY.md"
    );
}

#[test]
fn readme_names_the_two_commands_ci_and_the_main_job_run() {
    let readme = read("README.md");
    for command in ["    bash scripts/bench.sh", "    bash scripts/test.sh"] {
        assert!(readme.lines().any(|l| l == command), "README.md lost the command line '{}'", command.trim());
    }
    assert!(read(".ci/run").lines().any(|l| l.trim() == "bash scripts/test.sh"), ".ci/run no longer runs bash scripts/test.sh");
}

/// The methods table: `| method | family | what it does |` under
/// "## The methods", each method in backticks.
#[test]
fn readme_methods_table_names_every_registered_method_and_nothing_else() {
    let readme = read("README.md");
    let lines = section(&readme, "The methods");
    let table: Vec<Vec<String>> = lines.iter().filter(|l| l.starts_with('|')).map(|l| cells(l)).collect();
    assert!(table.len() > 2, "README.md: no table under '## The methods'");
    assert_eq!(table[0][..2], ["method", "family"], "README.md methods table header: {:?}", table[0]);
    let mut documented: BTreeMap<String, String> = BTreeMap::new();
    for row in &table[2..] {
        let name = row[0].trim_matches('`').to_string();
        assert!(documented.insert(name.clone(), row[1].clone()).is_none(), "README.md lists '{name}' twice");
    }
    let registry = registry::builtin();
    let registered: BTreeMap<String, String> =
        registry.methods().iter().map(|m| (m.name.to_string(), m.family.name.to_string())).collect();
    let missing: Vec<&String> = registered.keys().filter(|n| !documented.contains_key(*n)).collect();
    let gone: Vec<&String> = documented.keys().filter(|n| !registered.contains_key(*n)).collect();
    assert!(
        missing.is_empty() && gone.is_empty(),
        "README.md's methods table and src/algo/registry.rs disagree: registered but not in the table {missing:?}; \
         in the table but not registered {gone:?}"
    );
    for (name, family) in &registered {
        assert_eq!(&documented[name], family, "README.md: '{name}' is of the family '{family}' (MethodInfo::family)");
    }
}

/// GitHub's anchor for a heading: lower case, backticks and punctuation
/// dropped, spaces to hyphens.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// Text outside code: fenced blocks, indented blocks and inline code spans
/// left out (a link written there is an example, not a link).
fn prose(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let (mut fenced, mut indented, mut after_blank) = (false, false, true);
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        // An indented code block starts after a blank line (a list item's
        // continuation lines follow their text).
        indented = line.starts_with("    ") && (indented || after_blank) && !line.trim_start().starts_with(['-', '*', '|']);
        after_blank = line.trim().is_empty();
        if fenced || indented {
            continue;
        }
        let mut kept = String::new();
        let mut in_code = false;
        for c in line.chars() {
            if c == '`' {
                in_code = !in_code;
            } else if !in_code {
                kept.push(c);
            }
        }
        out.push(kept);
    }
    out
}

fn headings(text: &str) -> BTreeSet<String> {
    let mut fenced = false;
    let mut out = BTreeSet::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced && line.starts_with('#') {
            out.insert(slug(line.trim_start_matches('#')));
        }
    }
    out
}

/// `[text](target)` targets of a page's prose.
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in prose(text) {
        let mut rest = line.as_str();
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            let end = after.find(')').unwrap_or(after.len());
            out.push(after[..end].trim().to_string());
            rest = &after[end..];
        }
    }
    out
}

fn pages() -> Vec<PathBuf> {
    let mut pages: Vec<PathBuf> = ["README.md", "results/README.md", "results/HISTORY.md", "data/README.md", "data/tf/README.md"]
        .iter()
        .map(|p| root().join(p))
        .filter(|p| p.is_file())
        .collect();
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    pages.extend(docs);
    pages
}

#[test]
fn every_relative_link_in_the_documents_resolves() {
    let mut broken = Vec::new();
    let mut checked = 0;
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        let dir = page.parent().unwrap();
        let name = page.strip_prefix(root()).unwrap().display().to_string();
        for target in links(&text) {
            if target.contains("://") || target.starts_with("mailto:") || target.is_empty() {
                continue;
            }
            checked += 1;
            let (file, anchor) = match target.split_once('#') {
                Some((f, a)) => (f, Some(a)),
                None => (target.as_str(), None),
            };
            let path: PathBuf = if file.is_empty() { page.clone() } else { dir.join(file) };
            if !path.exists() {
                broken.push(format!("{name}: ({target}): {} does not exist", rel(&path)));
                continue;
            }
            if let Some(anchor) = anchor.filter(|_| path.is_file() && path.extension().is_some_and(|e| e == "md")) {
                let heads = headings(&std::fs::read_to_string(&path).unwrap());
                if !heads.contains(anchor) {
                    broken.push(format!("{name}: ({target}): no heading '#{anchor}' in {}", rel(&path)));
                }
            }
        }
    }
    assert!(checked > 50, "only {checked} links found: the link scanner is broken");
    assert!(broken.is_empty(), "broken links in the documents:\n{}", broken.join("\n"));
}

fn rel(p: &Path) -> String {
    p.strip_prefix(root()).map_or_else(|_| p.display().to_string(), |r| r.display().to_string())
}

#[test]
fn the_link_scanner_reads_links_headings_and_skips_code() {
    let page = "# Title\n\n## Where the data is found\n\nSee [a](a.md#where-the-data-is-found) and `[no](code.md)`.\n\n    [no](indented.md)\n\n```\n[no](fenced.md)\n# not a heading\n```\n- [b](b.md), [c](../c.md)\n";
    assert_eq!(links(page), ["a.md#where-the-data-is-found", "b.md", "../c.md"]);
    let heads = headings(page);
    assert!(heads.contains("where-the-data-is-found") && heads.contains("title") && !heads.contains("not-a-heading"), "{heads:?}");
    assert_eq!(slug(" The suite, its peers and `tracking` "), "the-suite-its-peers-and-tracking");
    assert_eq!(slug("Adaptive image-space refinement (`adaptive=TOL`)"), "adaptive-image-space-refinement-adaptivetol");
}

//! No function in `src/` longer than [`MAX_LINES`] (issue 36: short
//! constructors, GPU resources built by small named steps). Counted from
//! the line of `fn` to the line of its closing brace; test code
//! (`#[cfg(test)]` items and the files they declare) is left out. No GPU.

use std::path::{Path, PathBuf};

#[path = "common/source.rs"]
mod source;
use source::{is_ident, skip_ws};

/// The most lines a function of `src/` may take.
const MAX_LINES: usize = 100;

/// Functions still over the limit, each with the length it had when listed:
/// the list may only shrink. A listed function that grows, or that is
/// split (or gone), fails the test until its line is changed or removed.
/// (file, function, lines)
const NOT_YET_SPLIT: &[(&str, &str, usize)] = &[];

/// (line, name, lines) of every function of the non-test code of a file.
fn functions(text: &str) -> Vec<(usize, String, usize)> {
    let code = source::code_only(text);
    let code = source::without_test_items(&code);
    let line_at = |i: usize| 1 + code[..i].iter().filter(|&&c| c == b'\n').count();
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(at) = find_word(&code, i, b"fn") {
        i = at + 2;
        let name_start = skip_ws(&code, i);
        let name_len = code[name_start..].iter().take_while(|&&c| c.is_ascii_alphanumeric() || c == b'_').count();
        if name_len == 0 {
            continue; // `fn(` as a type
        }
        let name = String::from_utf8_lossy(&code[name_start..name_start + name_len]).into_owned();
        let Some(open) = source::body_start(&code, name_start + name_len) else { continue };
        let close = source::matching(&code, open);
        out.push((line_at(at), name, line_at(close) - line_at(at) + 1));
    }
    out
}

/// The next `word` standing alone at or after `from`.
fn find_word(b: &[u8], from: usize, word: &[u8]) -> Option<usize> {
    let mut i = from;
    while i + word.len() <= b.len() {
        if &b[i..i + word.len()] == word
            && (i == 0 || !is_ident(b[i - 1]))
            && b.get(i + word.len()).is_none_or(|&c| !is_ident(c))
        {
            return Some(i);
        }
        i += 1;
    }
    None
}

/// Files of `src/` declared as test modules (`#[cfg(test)] mod x;` in `file`).
fn test_files(file: &Path, text: &str) -> Vec<PathBuf> {
    let code = String::from_utf8(source::code_only(text)).unwrap();
    let dir = match file.file_name() {
        Some(n) if n == "mod.rs" || n == "lib.rs" => file.parent().unwrap().to_path_buf(),
        _ => file.with_extension(""),
    };
    code.split("#[cfg(test)]")
        .skip(1)
        .filter_map(|rest| {
            let words: Vec<&str> = rest.split_whitespace().take(2).collect();
            let name = words.get(1)?.strip_suffix(';')?;
            (words[0] == "mod").then(|| dir.join(format!("{name}.rs")))
        })
        .collect()
}

fn rs_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rs_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// Every function of `src/` over the limit: (file relative to the
/// repository, line, name, lines).
fn long_functions(repo: &Path) -> Vec<(String, usize, String, usize)> {
    let mut files = Vec::new();
    rs_files(&repo.join("src"), &mut files);
    files.sort();
    let texts: Vec<(PathBuf, String)> = files.into_iter().map(|f| {
        let t = std::fs::read_to_string(&f).unwrap();
        (f, t)
    }).collect();
    let tests: Vec<PathBuf> = texts.iter().flat_map(|(f, t)| test_files(f, t)).collect();
    let mut out = Vec::new();
    for (f, t) in &texts {
        if tests.contains(f) {
            continue;
        }
        let rel = f.strip_prefix(repo).unwrap().to_string_lossy().into_owned();
        for (line, name, n) in functions(t) {
            if n > MAX_LINES {
                out.push((rel.clone(), line, name, n));
            }
        }
    }
    out
}

#[test]
fn no_function_in_src_is_longer_than_the_limit() {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let long = long_functions(&repo);
    let mut problems = Vec::new();
    for (file, line, name, n) in &long {
        match NOT_YET_SPLIT.iter().find(|(f, fname, _)| f == file && fname == name) {
            Some(&(_, _, listed)) if *n > listed => problems.push(format!(
                "{file}:{line}: fn {name} is {n} lines, longer than the {listed} it is listed with in NOT_YET_SPLIT: split it into named steps"
            )),
            Some(_) => {}
            None => problems.push(format!(
                "{file}:{line}: fn {name} is {n} lines, over the limit of {MAX_LINES}: split it into named steps"
            )),
        }
    }
    for (file, name, listed) in NOT_YET_SPLIT {
        if !long.iter().any(|(f, _, n, _)| f == file && n == name) {
            problems.push(format!(
                "{file}: fn {name} (listed at {listed} lines) is no longer over {MAX_LINES} lines: remove it from NOT_YET_SPLIT"
            ));
        }
    }
    assert!(problems.is_empty(), "functions of src/ over {MAX_LINES} lines:\n  {}", problems.join("\n  "));
}

/// The scan finds a long function, leaves short ones, test code and `fn`
/// types alone, and counts from `fn` to the closing brace.
#[test]
fn the_scan_counts_function_bodies() {
    let body = "    let x = 1;\n".repeat(120);
    let text = format!(
        "type F = fn(u32) -> u32;\nfn short(a: [u8; 4]) -> u8 {{\n    a[0]\n}}\n\npub(crate) fn long() {{\n{body}    let s = \"}}\";\n}}\n\
         trait T {{ fn decl(&self); }}\n#[cfg(test)]\nmod tests {{\n    fn long_test() {{\n{body}    }}\n}}\n"
    );
    let found = functions(&text);
    assert_eq!(found, [(2, "short".to_string(), 3), (6, "long".to_string(), 123)], "{found:?}");
}

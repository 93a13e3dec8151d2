//! Where the shipped data (`data/`: meshes, volumes, terrain, transfer
//! functions) is found, for a binary run from the source tree or installed
//! elsewhere (`cargo install`): the first of
//!
//! 1. `VOLBENCH_DATA`, when set and not empty (taken as given: a wrong path
//!    is reported by the loader, naming the file);
//! 2. `data/` beside the executable (an installed copy ships it there);
//! 3. `data/` of the source tree the binary was built from.
//!
//! When none exists the source tree's path is returned, so that the error
//! names a path; [`search_note`] says where else it looked.

use std::path::{Path, PathBuf};

/// The data directory (see the module documentation for the order).
pub fn data_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("VOLBENCH_DATA").filter(|d| !d.is_empty()) {
        return PathBuf::from(d);
    }
    beside_executable().filter(|d| d.is_dir()).unwrap_or_else(source_tree)
}

/// `data/` beside the running executable, when its path is known.
fn beside_executable() -> Option<PathBuf> {
    Some(std::env::current_exe().ok()?.parent()?.join("data"))
}

/// `data/` of the source tree this binary was built from.
fn source_tree() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data")
}

/// For error messages: where the data was looked for and how to point at it.
pub fn search_note() -> String {
    let beside = beside_executable().map_or_else(|| "(executable path unknown)".into(), |p| p.display().to_string());
    format!(
        "the data directory is VOLBENCH_DATA, else {beside}, else {} (set VOLBENCH_DATA to the folder holding plot3d/, volumes/, terrain/, tf/)",
        source_tree().display()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_source_tree_is_found_and_the_note_names_the_variable() {
        // Test binaries live in target/, with no data/ beside them.
        if std::env::var_os("VOLBENCH_DATA").is_none() {
            assert_eq!(data_dir(), source_tree());
        }
        assert!(data_dir().join("tf").is_dir());
        assert!(search_note().contains("VOLBENCH_DATA"));
    }
}

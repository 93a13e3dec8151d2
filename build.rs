//! Records the git commit the binary was built from, so every result says
//! which code produced it ("unknown" outside a git checkout).

fn main() {
    let sha = std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".into());
    let dirty = std::process::Command::new("git")
        .args(["status", "--porcelain", "--untracked-files=no"])
        .output()
        .ok()
        .is_some_and(|o| o.status.success() && !o.stdout.is_empty());
    println!("cargo:rustc-env=VOLBENCH_GIT_SHA={sha}{}", if dirty { "-dirty" } else { "" });
    // Where HEAD and the index really are (in a worktree `.git` is a file;
    // a path that does not exist would make cargo re-run this every build).
    for what in ["HEAD", "index"] {
        let path = std::process::Command::new("git")
            .args(["rev-parse", "--git-path", what])
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
            .filter(|p| std::path::Path::new(p).exists());
        match path {
            Some(p) => println!("cargo:rerun-if-changed={p}"),
            None => println!("cargo:rerun-if-changed=build.rs"),
        }
    }
}

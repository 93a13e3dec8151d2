#!/usr/bin/env bash
# The main job: installs what volbench needs (scripts/setup.sh), builds it,
# and runs the benchmark suite into results/<run-id>/ (UTC time): every
# registered method on every shipped dataset of its kind at 512x512, with
# VTK's renderers measured in the same run, alternating with volbench's
# (scripts/install-vtk.sh; if VTK cannot be installed the suite runs without
# peers and the report says so), then after each dataset each peer renderer
# again with the two fastest runs at no more error in three alternating
# rounds (`--rounds`), the report quoting the better run's median ratio.
# It writes summary.json, summary.csv, report.md, plots, the montage and
# every run's images.
# Extra arguments go to `volbench suite` (e.g. --filter oxygenpost).
# The longer sweeps (run time against error per mesh, VICP vs balanced
# tables) are scripts/sweeps.sh; criterion benches are `cargo bench`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo build --release --locked
bin=./target/release/volbench
$bin info > /dev/null
out="results/$(date -u +%Y%m%dT%H%M%SZ)"
if bash scripts/install-vtk.sh; then
    $bin suite --peers vtk --out "$out" "$@"
else
    echo "bench: VTK could not be installed; the suite runs without peers" >&2
    $bin suite --out "$out" "$@"
fi
echo "results: $out (report: $out/report.md)"

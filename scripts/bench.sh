#!/usr/bin/env bash
# The main job: installs what volbench needs (scripts/setup.sh), builds it,
# and runs the benchmark suite into results/runs/<UTC time>/:
#   1. VICP against balanced cell projection on the blunt fin and the oxygen
#      post at 512x512 (JSON per run, PNGs of the reference view and their
#      difference from the f64 reference, comparison.md), table printed;
#   2. run time against error on both meshes (pareto/<mesh>/pareto.{csv,md,png});
#   3. the suite: every registered method on every shipped dataset of its kind
#      (suite/: summary.json, summary.csv, report.md, plots, montage), with
#      VTK's renderers measured in the same run (scripts/install-vtk.sh; if
#      VTK cannot be installed the suite runs without peers and says so).
# Extra arguments go to `volbench compare` (e.g. --frames 30). criterion
# benches of the hot paths are separate: `cargo bench`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo build --release --locked
out="results/runs/$(date -u +%Y%m%dT%H%M%SZ)"
bin=./target/release/volbench
$bin info > /dev/null
$bin compare --data bluntfin,oxygenpost --size 512x512 --frames 20 --warmup 3 --out "$out" "$@"
for mesh in bluntfin oxygenpost; do
    $bin pareto --data "$mesh" --size 512x512 --frames 5 --warmup 1 --out "$out/pareto/$mesh" > /dev/null
done
if bash scripts/install-vtk.sh; then
    $bin suite --peers vtk --out "$out/suite"
else
    echo "bench: VTK could not be installed; the suite runs without peers" >&2
    $bin suite --out "$out/suite"
fi
echo "results: $out"

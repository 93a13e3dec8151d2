#!/usr/bin/env bash
# The longer sweeps behind the tables of results/HISTORY.md (not part of the main job):
#   1. VICP against balanced cell projection on the blunt fin and the oxygen
#      post at 512x512 (JSON per run, PNGs of the reference view and their
#      difference from the f64 reference, comparison.md);
#   2. run time against error (pareto/<dataset>/pareto.{csv,md,json,png}):
#      every method of the dataset's kind over its accuracy options.
# Into results/runs/sweeps-<UTC time>/. Arguments: datasets for the pareto
# sweeps (default: bluntfin oxygenpost chest-ct). At 512x512 a mesh's sweep
# takes several minutes per method on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo build --release --locked
bin=./target/release/volbench
out="results/runs/sweeps-$(date -u +%Y%m%dT%H%M%SZ)"
$bin compare --data bluntfin,oxygenpost --size 512x512 --frames 20 --warmup 3 --out "$out"
datasets=("$@")
[ ${#datasets[@]} -gt 0 ] || datasets=(bluntfin oxygenpost chest-ct)
for d in "${datasets[@]}"; do
    $bin pareto --data "$d" --size 512x512 --frames 5 --warmup 1 --out "$out/pareto/$d" > /dev/null
done
echo "results: $out"

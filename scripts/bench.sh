#!/usr/bin/env bash
# The main job: installs what volbench needs (scripts/setup.sh), builds it,
# and runs the benchmark suite: VICP against balanced cell projection on the
# blunt fin and the oxygen post at 512x512, writing JSON, PNGs and a Markdown
# table to results/runs/<UTC time>/ and printing the table.
# Extra arguments go to `volbench compare` (e.g. --frames 30).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo build --release --locked
out="results/runs/$(date -u +%Y%m%dT%H%M%SZ)"
./target/release/volbench compare --meshes bluntfin,oxygenpost --size 512x512 --frames 20 --warmup 3 --out "$out" "$@"
echo "results: $out"

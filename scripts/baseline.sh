#!/usr/bin/env bash
# Regenerate the committed tracking baseline (results/baseline/quick/) that
# scripts/test.sh compares against: the quick suite, same binary as CI.
# Run it when a change is meant to move a count or an error, and commit the
# result with a message saying which figure moved and why.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo build --locked
tmp="$(mktemp -d)/quick"
VOLBENCH_VALIDATION=1 ./target/debug/volbench suite --quick --out "$tmp"
rm -rf results/baseline/quick
mkdir -p results/baseline
cp -r "$tmp" results/baseline/quick
echo "baseline: results/baseline/quick"

#!/usr/bin/env bash
# Regenerate the committed tracking baselines that scripts/test.sh compares
# against, same binary as CI: the quick suite (results/baseline/quick/) and
# the counted suite (results/baseline/count/: `suite --quick --count` on the
# datasets listed in results/baseline/count/filter). `--count-only`: the
# counted one alone.
# Run it when a change is meant to move a count or an error, and commit the
# result with a message saying which figure moved and why.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo build --locked
if [ "${1:-}" != "--count-only" ]; then
    tmp="$(mktemp -d)/quick"
    VOLBENCH_VALIDATION=1 ./target/debug/volbench suite --quick --out "$tmp"
    rm -rf results/baseline/quick
    mkdir -p results/baseline
    cp -r "$tmp" results/baseline/quick
    # The suite's --out lock (fsio::lock_out_dir) is no result.
    rm -f results/baseline/quick/.volbench-lock
    echo "baseline: results/baseline/quick"
fi
# Counted: only the summary and the run records are kept (no images worth keeping at 64x64).
tmp="$(mktemp -d)/count"
./target/debug/volbench suite --quick --count $(cat results/baseline/count/filter) --out "$tmp"
rm -rf results/baseline/count/summary.json results/baseline/count/runs
cp "$tmp/summary.json" results/baseline/count/
echo "baseline: results/baseline/count"

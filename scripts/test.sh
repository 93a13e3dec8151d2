#!/usr/bin/env bash
# The test command: installs what the tests need (scripts/setup.sh), runs
# every test with the Vulkan validation layer on (GPU tests fail on any
# validation message, including synchronization validation), then the quick
# suite and `volbench compare` against the committed baseline
# (results/baseline/quick/): counts must match exactly and errors must not
# grow; times are not compared (`--no-times`: shared runners are noisy, and
# without it moved times are only notes against a baseline from another
# machine or sitting, docs/tracking.md). Then the counted
# suite (`suite --quick --count` on the cheapest tet mesh and volume, under
# callgrind, beside the quick suite) against results/baseline/count/:
# instructions per phase within 1 % (docs/tracking.md): this is where CI
# tracks speed.
# Arguments go to `cargo test` and skip the suite step (a developer's subset).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export VOLBENCH_VALIDATION=1
export VK_LAYER_ENABLES=VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT
# Lints first: clippy on every target, any warning an error (the toolchain's
# clippy component; rustup installs it with the default profile).
if [ $# -eq 0 ]; then
    cargo clippy --locked --all-targets -- -D warnings
fi
cargo test --locked "$@"
if [ $# -eq 0 ]; then
    # cargo test built target/debug/volbench for the CLI tests: the same binary.
    out="$(mktemp -d)"
    # The counted suite runs beside the quick one: valgrind runs a process
    # on one core, and neither suite's compared figures depend on time. It
    # runs in a process group of its own (setsid: no job control here, so
    # it is not a group leader and keeps its pid), killed whole on exit:
    # its valgrind children stay in its group (harness/child.rs).
    setsid ./target/debug/volbench suite --quick --count $(cat results/baseline/count/filter) --out "$out/count" > "$out/count.log" 2>&1 &
    counting=$!
    trap 'kill -- -$counting 2>/dev/null || true' EXIT
    ./target/debug/volbench suite --quick --out "$out/quick"
    ./target/debug/volbench compare results/baseline/quick/summary.json "$out/quick/summary.json" --no-times
    status=0
    wait $counting || status=$?
    trap - EXIT
    cat "$out/count.log"
    if [ $status -ne 0 ]; then
        echo "test: the counted suite failed (exit status $status)" >&2
        exit $status
    fi
    ./target/debug/volbench compare results/baseline/count/summary.json "$out/count/summary.json" --no-times
fi

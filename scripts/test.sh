#!/usr/bin/env bash
# The test command: installs what the tests need (scripts/setup.sh), then runs
# every test with the Vulkan validation layer on (GPU tests fail on any
# validation message, including synchronization validation).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export VOLBENCH_VALIDATION=1
export VK_LAYER_ENABLES=VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT
cargo test --locked "$@"

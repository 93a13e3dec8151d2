#!/usr/bin/env bash
# A bounded fuzz run of every cargo-fuzz target listed in fuzz/Cargo.toml
# (targets added later are picked up without changing this script):
#
#   bash scripts/fuzz.sh [SECONDS]      # SECONDS per target, default 60
#
# Needs a nightly toolchain (`cargo +nightly`); installs cargo-fuzz when it
# is missing. For each target it creates fuzz/corpus/<target> (libFuzzer
# refuses a corpus folder that does not exist) and fuzz/artifacts/<target>,
# adds fuzz/seeds/<target>/ and fuzz/<target>.dict when they exist, and runs
# libFuzzer for SECONDS with a 10 s limit per input. Every target runs even
# if an earlier one fails; the exit status is non-zero if any target found a
# crash (the input is in fuzz/artifacts/<target>/; see fuzz/README.md for
# turning it into a regression test).
set -euo pipefail
cd "$(dirname "$0")/.."

seconds="${1:-60}"
if ! [[ "$seconds" =~ ^[1-9][0-9]*$ ]]; then
    echo "usage: bash scripts/fuzz.sh [SECONDS per target, a positive integer; default 60]" >&2
    exit 2
fi
if ! cargo +nightly --version >/dev/null 2>&1; then
    echo "fuzz.sh: cargo-fuzz needs a nightly toolchain: rustup toolchain install nightly" >&2
    exit 2
fi
if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "fuzz.sh: installing cargo-fuzz" >&2
    cargo install --locked cargo-fuzz
fi

# The targets, as cargo-fuzz reads them from fuzz/Cargo.toml.
mapfile -t targets < <(cargo +nightly fuzz list)
if [[ ${#targets[@]} -eq 0 ]]; then
    echo "fuzz.sh: no fuzz targets in fuzz/Cargo.toml" >&2
    exit 2
fi

failed=()
for target in "${targets[@]}"; do
    corpus="fuzz/corpus/$target"
    mkdir -p "$corpus" "fuzz/artifacts/$target"
    dirs=("$corpus")
    [[ -d "fuzz/seeds/$target" ]] && dirs+=("fuzz/seeds/$target")
    options=("-max_total_time=$seconds" "-timeout=10")
    [[ -f "fuzz/$target.dict" ]] && options+=("-dict=fuzz/$target.dict")
    echo "fuzz.sh: $target for ${seconds}s (${dirs[*]} ${options[*]})" >&2
    if ! cargo +nightly fuzz run "$target" "${dirs[@]}" -- "${options[@]}"; then
        failed+=("$target")
    fi
done

if [[ ${#failed[@]} -gt 0 ]]; then
    echo "fuzz.sh: crashes in: ${failed[*]} (inputs in fuzz/artifacts/<target>/)" >&2
    exit 1
fi
echo "fuzz.sh: no crash in ${#targets[@]} targets (${targets[*]}), ${seconds}s each" >&2

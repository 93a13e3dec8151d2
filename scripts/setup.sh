#!/usr/bin/env bash
# Installs what volbench needs on a fresh Debian 12 / Ubuntu machine (run as root),
# idempotently: the Vulkan loader, Mesa's lavapipe driver, the validation layer and
# shaderc's libraries (and a font for plot labels, valgrind and libc6-dbg for counted runs: the debug symbols name glibc's allocator, which counts leave out), then merges Debian's static shaderc/glslang/SPIRV-Tools
# archives into one (Debian's libshaderc.so does not link as shipped; see
# ../shared/PLATFORM.md) under .shaderc/, where .cargo/config.toml points shaderc-sys.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(mesa-vulkan-drivers libvulkan1 libvulkan-dev vulkan-validationlayers
          libshaderc-dev glslang-dev spirv-tools build-essential pkg-config
          fonts-dejavu-core valgrind libc6-dbg)

bash scripts/ensure-packages.sh "${packages[@]}"

if ! command -v cargo >/dev/null 2>&1; then
    echo "setup: cargo not found; install a Rust toolchain (rustup) first" >&2
    exit 1
fi

# One archive holding shaderc and everything it needs from glslang and SPIRV-Tools.
libdir=/usr/lib/$(gcc -print-multiarch 2>/dev/null || echo x86_64-linux-gnu)
out=.shaderc/libshaderc_combined.a
if [ ! -s "$out" ] || [ "$out" -ot "$libdir/libshaderc_combined.a" ]; then
    mkdir -p .shaderc
    script=.shaderc/merge.mri
    echo "CREATE $out" > "$script"
    for lib in shaderc_combined glslang MachineIndependent GenericCodeGen OSDependent \
               OGLCompiler HLSL SPIRV glslang-default-resource-limits SPIRV-Tools-opt SPIRV-Tools; do
        if [ -f "$libdir/lib$lib.a" ]; then
            echo "ADDLIB $libdir/lib$lib.a" >> "$script"
        else
            echo "setup: $libdir/lib$lib.a missing (is libshaderc-dev / glslang-dev installed?)" >&2
            exit 1
        fi
    done
    printf 'SAVE\nEND\n' >> "$script"
    ar -M < "$script"
    ranlib "$out"
    # shaderc-sys caches where it found the library; make it look again.
    cargo clean -p shaderc-sys --release >/dev/null 2>&1 || true
    cargo clean -p shaderc-sys >/dev/null 2>&1 || true
    echo "setup: merged shaderc archive at $out"
fi

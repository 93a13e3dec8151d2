#!/usr/bin/env bash
# Installs the peer renderers for `volbench suite --peers vtk`, idempotently:
# VTK's Python wheel and numpy in a private virtual environment (.venv-vtk/ in
# the checkout, or $VOLBENCH_VTK_VENV), and the system libraries the wheel
# needs to render offscreen on Mesa's llvmpipe through EGL (run as root on a
# fresh Debian 12 / Ubuntu; see ../../shared/PLATFORM.md). Nothing else of
# volbench needs Python.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=${VOLBENCH_VTK_VENV:-.venv-vtk}
# VTK's wheel for CPython 3.8-3.13 on x86_64 Linux; the version volbench was checked with.
vtk_req=${VOLBENCH_VTK_VERSION:-vtk>=9.3,<10}

packages=(python3 python3-venv libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libglx-mesa0
          libx11-6 libxrender1 libxcursor1 libxext6 libxfixes3 libxinerama1 libxft2)
bash scripts/ensure-packages.sh "${packages[@]}"

# The system interpreter, not one a version manager put first on PATH.
py=/usr/bin/python3
[ -x "$py" ] || py=$(command -v python3)
if [ ! -x "$venv/bin/python" ]; then
    echo "install-vtk: creating the virtual environment $venv"
    "$py" -m venv "$venv"
fi
if ! "$venv/bin/python" -c "import vtkmodules, numpy" >/dev/null 2>&1; then
    echo "install-vtk: installing VTK ($vtk_req) and numpy into $venv"
    "$venv/bin/python" -m pip install --quiet --upgrade pip
    "$venv/bin/python" -m pip install --quiet "$vtk_req" numpy
fi
# The check volbench runs too: can the wheel open an offscreen window here?
"$venv/bin/python" scripts/peers/vtk_peer.py --check

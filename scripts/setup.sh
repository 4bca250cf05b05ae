#!/usr/bin/env bash
# Fresh-machine setup for MatrixTree on Debian 12. Safe to re-run: every step
# checks first and does nothing when its result is already in place.
#
#   1. apt packages (Debian's VTK 9.1 SDK, GoogleTest, PoCL OpenCL, Xvfb)
#   2. .venv made from /usr/bin/python3 with --system-site-packages, so it
#      sees Debian's VTK; pyvista 0.46.5 installed without pip's `vtk` wheel
#   3. CMake configure + build into build/, with the benchmark drivers
#      (MATRIXTREE_BENCHMARKS=ON: bench/*.py run them), and the engine's own
#      Python extension (python/bindings, what `pip install .` builds) into
#      build/engine-python/
#   4. a .pth file so .venv finds python/ (matrixtree), build/python
#      (matrixtree_vtk) and build/engine-python/python (matrixtree_engine)
#      without PYTHONPATH
#   5. the ParaView plugin (paraview/) against ParaView 5.11's own VTK 9.2 in
#      build-paraview/, with python3-paraview unpacked there for pvbatch
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

SYS_PYTHON=/usr/bin/python3          # the Python Debian's VTK is built for
VENV="$ROOT/.venv"
VPY="$VENV/bin/python"
BUILD_DIR="$ROOT/build"
PYVISTA_VERSION=0.46.5               # newest pyvista that works with VTK 9.1

T0=$SECONDS
say() { printf '[setup %3ds] %s\n' "$((SECONDS - T0))" "$*"; }
die() { printf '[setup] ERROR: %s\n' "$*" >&2; exit 1; }

# ---------------------------------------------------------------------------
# 1. Debian packages
# ---------------------------------------------------------------------------
APT_PACKAGES=(
  build-essential cmake
  libvtk9-dev python3-vtk9 python3-numpy python3-venv python3-pytest
  libgtest-dev
  pocl-opencl-icd ocl-icd-opencl-dev opencl-headers clinfo
  xvfb xauth
  openmpi-bin python3-mpi4py
  paraview paraview-dev
  libembree-dev
)

missing=()
for pkg in "${APT_PACKAGES[@]}"; do
  status="$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null || true)"
  [[ "$status" == "install ok installed" ]] || missing+=("$pkg")
done

if ((${#missing[@]})); then
  command -v apt-get >/dev/null || die "apt-get not found: this script targets Debian 12"
  SUDO=""
  if [[ "$(id -u)" -ne 0 ]]; then
    command -v sudo >/dev/null || die "not root and no sudo: install ${missing[*]} by hand"
    SUDO="sudo"
  fi
  say "apt: installing ${missing[*]}"
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  # paraview's Recommends (python3-paraview) conflict with python3-vtk9: nothing may be removed.
  removals="$(apt-get install -s --no-install-recommends "${missing[@]}" | grep '^Remv' || true)"
  [[ -z "$removals" ]] || die "installing ${missing[*]} would remove packages:"$'\n'"$removals"
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
  say "apt: done"
else
  say "apt: all ${#APT_PACKAGES[@]} packages present"
fi

[[ -x "$SYS_PYTHON" ]] || die "$SYS_PYTHON missing"
"$SYS_PYTHON" -c 'import vtkmodules.vtkCommonCore' 2>/dev/null \
  || die "$SYS_PYTHON cannot import Debian's VTK (python3-vtk9)"

# ---------------------------------------------------------------------------
# 2. Python virtual environment
# ---------------------------------------------------------------------------
# A .venv made from another Python (pyenv, conda) cannot see Debian's VTK:
# replace it.
if [[ -x "$VPY" ]] && ! "$VPY" -c 'import sys, vtkmodules.vtkCommonCore; assert sys.base_prefix == "/usr"' 2>/dev/null; then
  say "venv: $VENV does not use Debian's python3/VTK, recreating it"
  rm -rf "$VENV"
fi
if [[ ! -x "$VPY" ]]; then
  say "venv: creating .venv (--system-site-packages)"
  "$SYS_PYTHON" -m venv --system-site-packages "$VENV"
fi

# The packages we need, checked by import (pyvista at its pinned version).
venv_ready() {
  "$VPY" - "$PYVISTA_VERSION" <<'PY' 2>/dev/null
import sys
import meshio, pytest, tqdm, pyvista, embreex, nanobind
assert pyvista.__version__ == sys.argv[1], pyvista.__version__
PY
}

if venv_ready; then
  say "pip: pytest meshio tqdm embreex nanobind pyvista==$PYVISTA_VERSION already importable"
else
  say "pip: installing pytest meshio tqdm embreex nanobind pyvista==$PYVISTA_VERSION (without the vtk wheel)"
  export PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_NO_INPUT=1
  # Keep Debian's numpy: a pip numpy in .venv would shadow the one that
  # Debian's VTK (numpy_interface, numpy_support) was packaged with.
  constraints="$(mktemp)"
  trap 'rm -f "$constraints"' EXIT
  "$SYS_PYTHON" -c 'import numpy; print("numpy==" + numpy.__version__)' >"$constraints"
  # pyvista's own dependencies except `vtk` (from its wheel metadata:
  # matplotlib, numpy, pillow, pooch, scooby, typing-extensions, vtk).
  "$VPY" -m pip install -q -c "$constraints" \
    pytest meshio tqdm embreex nanobind \
    'matplotlib>=3.0.1' pillow pooch 'scooby>=0.5.1' 'typing-extensions>=4.10'
  "$VPY" -m pip install -q --no-deps "pyvista==$PYVISTA_VERSION"
  venv_ready || die "pip install finished but the packages do not import"
  say "pip: done"
fi

# pip must not have brought its own VTK: VTK has to be Debian's 9.1.
"$VPY" - <<'PY' || die "VTK check failed in .venv"
import vtkmodules, vtkmodules.vtkCommonCore as cc
version = cc.vtkVersion.GetVTKVersion()
assert version.startswith("9.1."), f"VTK {version} in .venv, expected Debian's 9.1"
assert vtkmodules.__file__.startswith("/usr/lib/python3/"), \
    f"vtkmodules comes from {vtkmodules.__file__}, not Debian's python3-vtk9"
import pyvista
PY
say "venv: VTK $("$VPY" -c 'import vtkmodules.vtkCommonCore as c; print(c.vtkVersion.GetVTKVersion())') (Debian), pyvista $("$VPY" -c 'import pyvista; print(pyvista.__version__)')"

# ---------------------------------------------------------------------------
# 3. CMake build
# ---------------------------------------------------------------------------
# cmake_build STAGE SOURCE_DIR BUILD_DIR [CMAKE_ARGS...]: configure and build a Release tree,
# logs in BUILD_DIR.
cmake_build() {
  local stage="$1" src="$2" dir="$3" name
  shift 3
  name="$(basename "$dir")"
  mkdir -p "$dir"
  say "$stage: configure $name/ (log: $name/configure.log)"
  if ! cmake -S "$src" -B "$dir" -DCMAKE_BUILD_TYPE=Release "$@" >"$dir/configure.log" 2>&1; then
    tail -n 40 "$dir/configure.log" >&2
    die "$stage: cmake configure of $name/ failed"
  fi
  say "$stage: build -j$(nproc) (log: $name/build.log)"
  if ! cmake --build "$dir" -j"$(nproc)" >"$dir/build.log" 2>&1; then
    grep -E 'error|Error' "$dir/build.log" | head -n 40 >&2 || true
    die "$stage: build of $name/ failed, see $name/build.log"
  fi
}
# The benchmark drivers (MATRIXTREE_BENCHMARKS=ON) are built too: bench/*.py run them.
cmake_build cmake "$ROOT" "$BUILD_DIR" -DMATRIXTREE_BENCHMARKS=ON
n_warn="$(grep -c ': warning:' "$BUILD_DIR/build.log" || true)"
if ((n_warn)); then
  say "cmake: $n_warn compiler warning(s) in this build:"
  grep ': warning:' "$BUILD_DIR/build.log" | sort -u | head -n 20
fi

WRAPPED_DIR="$BUILD_DIR/python"
[[ -f "$WRAPPED_DIR/matrixtree_vtk/__init__.py" ]] \
  || die "matrixtree_vtk not found under $WRAPPED_DIR"

# The engine-only extension (no VTK), built for .venv's Python so that the tests can compare it
# with the VTK module; `pip install .` builds the same CMake entry for pip users.
ENGINE_DIR="$BUILD_DIR/engine-python"
cmake_build engine "$ROOT/python/bindings" "$ENGINE_DIR" \
  -DPython_EXECUTABLE="$VPY" -Dnanobind_DIR="$("$VPY" -m nanobind --cmake_dir)"

# ---------------------------------------------------------------------------
# 4. Python package and .pth
# ---------------------------------------------------------------------------
if [[ ! -f "$ROOT/python/matrixtree/__init__.py" ]]; then
  say "python: creating python/matrixtree/__init__.py"
  mkdir -p "$ROOT/python/matrixtree"
  cat >"$ROOT/python/matrixtree/__init__.py" <<'PY'
"""MatrixTree: block-sparse matrix trees for cell location, ray casting and
volume marching, with VTK and pyvista adapters.

The VTK classes come from the compiled ``matrixtree_vtk`` package, built
against Debian's VTK 9.1; use the project's ``.venv`` (``scripts/setup.sh``).
"""

from matrixtree_vtk import vtkMatrixTreeVersion

__version__ = vtkMatrixTreeVersion.GetVersion()
PY
fi

SITE_PACKAGES="$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
PTH="$SITE_PACKAGES/matrixtree.pth"
pth_text="$(printf '%s\n%s\n%s' "$ROOT/python" "$WRAPPED_DIR" "$ENGINE_DIR/python")"
if [[ ! -f "$PTH" || "$(cat "$PTH")" != "$pth_text" ]]; then
  printf '%s\n' "$pth_text" >"$PTH"
  say "python: wrote $PTH"
fi

"$VPY" -c 'import matrixtree_vtk, matrixtree_engine, matrixtree; print(matrixtree.__version__)' >/dev/null \
  || die ".venv cannot import matrixtree_vtk / matrixtree_engine / matrixtree"
say "ok: .venv/bin/python imports matrixtree $("$VPY" -c 'import matrixtree; print(matrixtree.__version__)') (took $((SECONDS - T0)) s)"

# ---------------------------------------------------------------------------
# 5. ParaView plugin (build-paraview/, ParaView 5.11 and its VTK 9.2)
# ---------------------------------------------------------------------------
# pvbatch needs ParaView's Python packages, which Debian ships in python3-paraview; that package
# conflicts with python3-vtk9 (Debian's VTK 9.1, the project's SDK), so it is unpacked into
# build-paraview/python3-paraview (dpkg -x touches no installed package) instead of installed.
T5=$SECONDS
PV_BUILD="$ROOT/build-paraview"
PV_UNPACKED="$PV_BUILD/python3-paraview"
pv_version="$(dpkg-query -W -f='${Version}' paraview)"
if [[ "$(cat "$PV_UNPACKED/VERSION" 2>/dev/null)" != "$pv_version" ]]; then
  say "paraview: unpacking python3-paraview $pv_version into build-paraview/python3-paraview"
  rm -rf "$PV_UNPACKED"
  mkdir -p "$PV_UNPACKED"
  deb_dir="$(mktemp -d)"
  apt_sudo=""
  [[ "$(id -u)" -eq 0 ]] || apt_sudo="sudo"
  if ! (cd "$deb_dir" && apt-get download -qq "python3-paraview=$pv_version" 2>/dev/null); then
    $apt_sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq
    (cd "$deb_dir" && apt-get download -qq "python3-paraview=$pv_version" 2>/dev/null) \
      || die "apt-get download python3-paraview=$pv_version failed"
  fi
  dpkg -x "$deb_dir"/python3-paraview_*.deb "$PV_UNPACKED"
  rm -rf "$deb_dir"
  printf '%s\n' "$pv_version" >"$PV_UNPACKED/VERSION"
fi
cmake_build paraview "$ROOT/paraview" "$PV_BUILD"
PV_PLUGIN="$PV_BUILD/lib/paraview-5.11/plugins/MatrixTree/MatrixTree.so"
[[ -f "$PV_PLUGIN" ]] || die "the plugin $PV_PLUGIN was not built"
for pkg in python3-vtk9 libvtk9-dev; do  # the VTK 9.1 SDK must have survived
  [[ "$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null)" == "install ok installed" ]] \
    || die "$pkg is no longer installed"
done
say "paraview: plugin $PV_PLUGIN (took $((SECONDS - T5)) s)"

#!/usr/bin/env bash
# Set up (idempotent), then run the C++ tests (ctest), the Python tests
# (pytest in .venv), the Python tests that need no VTK C++ classes in an
# isolated pip environment (build/venv-pip: the newest pip `vtk` and `pyvista`,
# the package installed with `pip install .`), the ParaView plugin tests
# (pvbatch), the MPI tests (mpirun) and the sanitizer/fuzz stages
# (scripts/sanitize.sh). Exits non-zero if setup or any stage fails.
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

T0=$SECONDS
bash scripts/setup.sh || { echo "[test] setup failed" >&2; exit 1; }
T_SETUP=$((SECONDS - T0))

echo "[test] ctest"
T1=$SECONDS
ctest --test-dir build --output-on-failure -j2 2>&1 | tee build/ctest.log
ctest_rc=${PIPESTATUS[0]}
T_CTEST=$((SECONDS - T1))

# Debian's VTK renders only through X: give pytest a virtual display when
# there is none, so pyvista/VTK rendering tests work headless.
PYTEST=(.venv/bin/python -m pytest -q)
if [[ -z "${DISPLAY:-}" ]] && command -v xvfb-run >/dev/null; then
  PYTEST=(xvfb-run -a "${PYTEST[@]}")
fi
echo "[test] pytest"
T2=$SECONDS
"${PYTEST[@]}" 2>&1 | tee build/pytest.log
pytest_rc=${PIPESTATUS[0]}
T_PYTEST=$((SECONDS - T2))

# What a pyvista user has: a venv without system site packages (pip's VTK and Debian's must
# never meet in one process), the newest `vtk` and `pyvista` wheels, and this package built by
# `pip install .` (the engine extension; no VTK C++ SDK). The CMake build folder is kept in
# build/pip-build, so a rerun recompiles only what changed. Needs PyPI.
PIP_VENV=build/venv-pip
# The Python tests that need no VTK C++ class of this project: there `import matrixtree` answers
# through the engine extension (matrixtree._backend). The package lives in site-packages, so the
# shared data folder is named explicitly.
PIP_TESTS=(tests/python/test_engine.py tests/python/test_filters.py tests/python/test_mesh_changes.py
           tests/python/test_matrixtree.py tests/python/test_cli.py tests/python/test_bench_tools.py
           tests/python/test_readme.py tests/python/test_reliability.py tests/python/test_quality.py
           tests/python/test_stability.py)
echo "[test] pip environment ($PIP_VENV): newest vtk + pyvista, pip install ."
T3=$SECONDS
pip_stage() {
  [[ -x "$PIP_VENV/bin/python" ]] || /usr/bin/python3 -m venv "$PIP_VENV" || return 1
  local pip=("$PIP_VENV/bin/python" -m pip -q --disable-pip-version-check)
  "${pip[@]}" install --upgrade vtk pyvista pytest tqdm meshio || return 1   # tqdm, meshio: optional features the tests use
  "${pip[@]}" install --config-settings=build-dir=build/pip-build . || return 1
  "$PIP_VENV/bin/python" -c 'import vtk, pyvista, matrixtree
assert matrixtree.EXTENSION == "matrixtree_engine", matrixtree.EXTENSION
print(f"[test] pip environment: vtk {vtk.vtkVersion.GetVTKVersion()}, pyvista {pyvista.__version__}, "
      f"matrixtree {matrixtree.__version__} ({matrixtree.EXTENSION}) from {matrixtree.__file__}")' || return 1
  # --pyargs: the installed package's docstring examples too (mpi.py needs mpi4py, not installed here).
  MATRIXTREE_DATA="${MATRIXTREE_DATA:-$ROOT/../shared/data}" \
    "$PIP_VENV/bin/python" -m pytest -q -p no:cacheprovider "${PIP_TESTS[@]}" --pyargs matrixtree \
    --ignore-glob='*/matrixtree/mpi.py'
}
pip_stage 2>&1 | tee build/pytest-pip.log
pip_rc=${PIPESTATUS[0]}
T_PIP=$((SECONDS - T3))

# The ParaView plugin (built by setup.sh into build-paraview/) through pvbatch, also under
# mpirun -np 2: tests/paraview runs in .venv and starts pvbatch for every ParaView step.
echo "[test] paraview"
T5=$SECONDS
"${PYTEST[@]}" tests/paraview 2>&1 | tee build/paraview.log
paraview_rc=${PIPESTATUS[0]}
T_PARAVIEW=$((SECONDS - T5))

# matrixtree.mpi under mpirun -np 2 and 4 (tests/mpi starts mpirun itself).
echo "[test] mpi"
T4=$SECONDS
"${PYTEST[@]}" tests/mpi 2>&1 | tee build/mpi.log
mpi_rc=${PIPESTATUS[0]}
T_MPI=$((SECONDS - T4))

# Sanitizers and fuzzing (scripts/sanitize.sh, docs/reliability.md): the stages named in
# $MATRIXTREE_SANITIZE_STAGES, default "tsan fuzz": a clang TSan build of the threaded tests (OpenMP
# through Archer); the fuzz harnesses (clang, libFuzzer, ASan+UBSan), each fuzzed
# $MATRIXTREE_FUZZ_SECONDS (default 10) from seed 1 after replaying its regressions, then the
# Python reader fuzzer as long. "asan" adds a GCC ASan+UBSan build of the engine, the VTK module's
# library and a C++ test subset (about 14 CPU-minutes: opt-in). "none" skips them all.
SAN_STAGES="${MATRIXTREE_SANITIZE_STAGES:-tsan fuzz}"
echo "[test] sanitize: $SAN_STAGES"
T6=$SECONDS
sanitize_stages() {
  local stage rc=0 t
  for stage in $SAN_STAGES; do
    t=$SECONDS
    if [[ "$stage" == "fuzz" ]]; then
      bash scripts/sanitize.sh fuzz "${MATRIXTREE_FUZZ_SECONDS:-10}" || rc=1
    else
      bash scripts/sanitize.sh "$stage" || rc=1
    fi
    echo "[test] sanitize stage $stage: $((SECONDS - t)) s"
  done
  return "$rc"
}
sanitize_rc=0
if [[ "$SAN_STAGES" != "none" ]]; then
  sanitize_stages 2>&1 | tee build/sanitize.log
  sanitize_rc=${PIPESTATUS[0]}
fi
T_SANITIZE=$((SECONDS - T6))

verdict() { if [[ "$1" -eq 0 ]]; then echo "PASS"; else echo "FAIL (exit $1)"; fi; }
echo
echo "================ summary ================"
echo "setup : ok (${T_SETUP} s)"
echo "ctest : $(verdict "$ctest_rc") (${T_CTEST} s) - $(grep -E 'tests passed|tests failed' build/ctest.log | tail -n 1)"
echo "pytest: $(verdict "$pytest_rc") (${T_PYTEST} s) - $(grep -E '(passed|failed|error|no tests ran)' build/pytest.log | tail -n 1)"
echo "pip   : $(verdict "$pip_rc") (${T_PIP} s) - $(grep -oE 'vtk [0-9.]+, pyvista [0-9.]+' build/pytest-pip.log | tail -n 1); $(grep -E '(passed|failed|error|no tests ran)' build/pytest-pip.log | tail -n 1)"
echo "paraview: $(verdict "$paraview_rc") (${T_PARAVIEW} s) - $(grep -E '(passed|failed|error|no tests ran)' build/paraview.log | tail -n 1)"
echo "mpi   : $(verdict "$mpi_rc") (${T_MPI} s) - $(grep -E '(passed|failed|error|no tests ran)' build/mpi.log | tail -n 1)"
echo "sanitize: $(verdict "$sanitize_rc") (${T_SANITIZE} s) - stages: $SAN_STAGES$(grep -oE 'stage [a-z]+: [0-9]+ s' build/sanitize.log 2>/dev/null | sed 's/^stage /; /' | tr -d '\n')"

[[ "$ctest_rc" -eq 0 && "$pytest_rc" -eq 0 && "$pip_rc" -eq 0 && "$paraview_rc" -eq 0 && "$mpi_rc" -eq 0 &&
  "$sanitize_rc" -eq 0 ]]

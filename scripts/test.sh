#!/usr/bin/env bash
# Set up (idempotent), then run the C++ tests (ctest), the Python tests (pytest in
# .venv), the ParaView plugin tests (pvbatch) and the MPI tests (mpirun). Exits
# non-zero if setup or any stage fails.
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

# The ParaView plugin (built by setup.sh into build-paraview/) through pvbatch, also under
# mpirun -np 2: tests/paraview runs in .venv and starts pvbatch for every ParaView step.
echo "[test] paraview"
T3=$SECONDS
"${PYTEST[@]}" tests/paraview 2>&1 | tee build/paraview.log
paraview_rc=${PIPESTATUS[0]}
T_PARAVIEW=$((SECONDS - T3))

# matrixtree.mpi under mpirun -np 2 and 4 (tests/mpi starts mpirun itself).
echo "[test] mpi"
T4=$SECONDS
"${PYTEST[@]}" tests/mpi 2>&1 | tee build/mpi.log
mpi_rc=${PIPESTATUS[0]}
T_MPI=$((SECONDS - T4))

verdict() { if [[ "$1" -eq 0 ]]; then echo "PASS"; else echo "FAIL (exit $1)"; fi; }
echo
echo "================ summary ================"
echo "setup : ok (${T_SETUP} s)"
echo "ctest : $(verdict "$ctest_rc") (${T_CTEST} s) - $(grep -E 'tests passed|tests failed' build/ctest.log | tail -n 1)"
echo "pytest: $(verdict "$pytest_rc") (${T_PYTEST} s) - $(grep -E '(passed|failed|error|no tests ran)' build/pytest.log | tail -n 1)"
echo "paraview: $(verdict "$paraview_rc") (${T_PARAVIEW} s) - $(grep -E '(passed|failed|error|no tests ran)' build/paraview.log | tail -n 1)"
echo "mpi   : $(verdict "$mpi_rc") (${T_MPI} s) - $(grep -E '(passed|failed|error|no tests ran)' build/mpi.log | tail -n 1)"

[[ "$ctest_rc" -eq 0 && "$pytest_rc" -eq 0 && "$paraview_rc" -eq 0 && "$mpi_rc" -eq 0 ]]

#!/usr/bin/env bash
# Sanitizer and fuzzing stages (docs/reliability.md), each in its own build folder with clang
# (Debian's clang 14 and its compiler-rt: ASan, UBSan, TSan, libFuzzer; LLVM's OpenMP runtime with
# its Archer tool for TSan). Needs scripts/setup.sh first (VTK, GoogleTest, .venv).
#
#   scripts/sanitize.sh asan  [SECONDS]  build-asan/: engine, VTK module and a test subset under
#                                        ASan+UBSan; run the C++ subset, then a Python smoke
#                                        suite with the ASan runtime preloaded
#   scripts/sanitize.sh tsan             build-tsan/: the concurrency and parallel tests under TSan
#   scripts/sanitize.sh fuzz  [SECONDS]  build-fuzz/: the libFuzzer harnesses (ASan+UBSan), each
#                                        run SECONDS (default 20) from seed 1 after replaying its
#                                        regressions, then the Python reader fuzzer as long
#
# Every stage exits non-zero on a sanitizer report, a test failure or a fuzz finding (whose
# input is left in build-fuzz/findings/). Longer fuzzing by hand: scripts/sanitize.sh fuzz 3600.
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
STAGE="${1:-}"
SECONDS_ARG="${2:-}"
JOBS="${MATRIXTREE_JOBS:-$(nproc)}"
T0=$SECONDS
say() { printf '[%s %4ds] %s\n' "$STAGE" "$((SECONDS - T0))" "$*"; }
die() { printf '[%s] ERROR: %s\n' "$STAGE" "$*" >&2; exit 1; }

# ---------------------------------------------------------------------------
# clang, compiler-rt and LLVM's OpenMP runtime (Debian 12: clang 14)
# ---------------------------------------------------------------------------
APT_PACKAGES=(clang libclang-rt-14-dev libomp-14-dev)
missing=()
for pkg in "${APT_PACKAGES[@]}"; do
  [[ "$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null || true)" == "install ok installed" ]] || missing+=("$pkg")
done
if ((${#missing[@]})); then
  SUDO=""
  [[ "$(id -u)" -ne 0 ]] && SUDO="sudo"
  say "apt: installing ${missing[*]}"
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null \
    || die "apt-get install ${missing[*]} failed"
fi
CC_BIN="$(command -v clang-14 || command -v clang)"
CXX_BIN="$(command -v clang++-14 || command -v clang++)"
[[ -x "$CXX_BIN" ]] || die "clang++ not found"
ASAN_RT="$("$CXX_BIN" -print-file-name=libclang_rt.asan-x86_64.so)"
ARCHER="$(dirname "$("$CXX_BIN" -print-file-name=libomp.so)")/libarcher.so"
[[ -f "$ARCHER" ]] || ARCHER="/usr/lib/llvm-14/lib/libarcher.so"
VPY="$ROOT/.venv/bin/python"
[[ -x "$VPY" ]] || die ".venv missing: run scripts/setup.sh first"

# configure DIR SANITIZERS TESTS [extra cmake args]: a Debug-like -O1 -g build (assertions on).
configure() {
  local dir="$1" sanitize="$2" tests="$3"
  shift 3
  mkdir -p "$ROOT/$dir"
  cmake -S "$ROOT" -B "$ROOT/$dir" -DCMAKE_C_COMPILER="$CC_BIN" -DCMAKE_CXX_COMPILER="$CXX_BIN" \
    -DCMAKE_BUILD_TYPE=Sanitize -DCMAKE_CXX_FLAGS_SANITIZE="-O1 -g" -DCMAKE_C_FLAGS_SANITIZE="-O1 -g" \
    -DMATRIXTREE_SANITIZE="$sanitize" -DMATRIXTREE_TESTS="$tests" -DMATRIXTREE_OPENCL=OFF \
    -DMATRIXTREE_BENCHMARKS=OFF "$@" >"$ROOT/$dir/configure.log" 2>&1 \
    || { tail -n 30 "$ROOT/$dir/configure.log" >&2; die "cmake configure of $dir failed"; }
}
build() {
  local dir="$1"
  shift
  cmake --build "$ROOT/$dir" -j"$JOBS" --target "$@" >"$ROOT/$dir/build.log" 2>&1 \
    || { grep -E 'error|Error' "$ROOT/$dir/build.log" | head -n 30 >&2; die "build in $dir failed (see $dir/build.log)"; }
}

# The C++ subset under ASan+UBSan: every engine area (trees, builds, cells, rays, volume, layout,
# parallel primitives) and the VTK classes' input checks, with the programs' slow real-mesh
# sweeps left to the normal build (ctest -E below): the full suite under ASan takes ~1 h here.
ASAN_TESTS="test_input_checks;test_concurrency;test_matrix_tree;test_build_sort;test_cells;test_cell_eval;test_edge_cases;test_layout;test_parallel;test_rays;test_render;test_block_sparse;test_volume;test_segment_filter;test_mt_watertight;test_sah;test_smoke"
ASAN_EXCLUDE='RealMesh|Real/|AllMeshes|turbineblade|lucy|nefertiti|horse|bunny|Large|Huge|Sweep'
# The Python smoke suite under ASan: the bad-input tests, and the wrappers' main paths.
SMOKE_TESTS=(tests/python/test_reliability.py tests/python/test_locator_batch.py tests/python/test_matrixtree.py
  tests/python/test_volume.py)

case "$STAGE" in
asan)
  configure build-asan "address,undefined" "$ASAN_TESTS"
  say "build (engine, VTK module, ${ASAN_TESTS//;/ })"
  build build-asan ${ASAN_TESTS//;/ } MatrixTreeFiltersPython Filters-matrixtree_vtk
  say "ctest (ASan+UBSan), excluding the real-mesh sweeps: /$ASAN_EXCLUDE/"
  ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:halt_on_error=1" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
    ctest --test-dir build-asan -j"$JOBS" --output-on-failure -E "$ASAN_EXCLUDE" >build-asan/ctest.log 2>&1
  rc=$?
  grep -E "tests passed|tests failed" build-asan/ctest.log | tail -n 1
  ((rc == 0)) || { grep -E "ERROR: AddressSanitizer|runtime error|Failed|\*\*\*" build-asan/ctest.log | head -n 30; die "ctest under ASan failed (build-asan/ctest.log)"; }
  say "pytest under ASan (the runtime preloaded; leaks of the interpreter not reported): ${SMOKE_TESTS[*]}"
  PYTEST=(env LD_PRELOAD="$ASAN_RT" "$VPY" -m pytest -q -p no:cacheprovider -o addopts="" "${SMOKE_TESTS[@]}")
  [[ -z "${DISPLAY:-}" ]] && command -v xvfb-run >/dev/null && PYTEST=(xvfb-run -a "${PYTEST[@]}")
  # build-asan/python first on the path: its matrixtree_vtk is the instrumented one.
  export PYTHONPATH="$ROOT/build-asan/python:$ROOT/python" ASAN_OPTIONS="detect_leaks=0:halt_on_error=1" \
    UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
  module="$(LD_PRELOAD="$ASAN_RT" "$VPY" -c 'import matrixtree_vtk; print(matrixtree_vtk.__file__)')"
  [[ "$module" == "$ROOT/build-asan/"* ]] || die "the smoke suite would load $module, not build-asan's module"
  "${PYTEST[@]}" >build-asan/pytest.log 2>&1
  rc=$?
  tail -n 1 build-asan/pytest.log
  ((rc == 0)) || { grep -E "ERROR: AddressSanitizer|runtime error|FAILED" build-asan/pytest.log | head -n 30; die "pytest under ASan failed (build-asan/pytest.log)"; }
  say "done"
  ;;
tsan)
  TSAN_TESTS="test_concurrency;test_parallel"
  configure build-tsan "thread" "$TSAN_TESTS"
  say "build (${TSAN_TESTS//;/ })"
  build build-tsan ${TSAN_TESTS//;/ }
  say "ctest under TSan (OpenMP through Archer: $ARCHER)"
  OMP_TOOL_LIBRARIES="$ARCHER" ARCHER_OPTIONS="verbose=0" TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1" \
    ctest --test-dir build-tsan -j"$JOBS" --output-on-failure >build-tsan/ctest.log 2>&1
  rc=$?
  grep -E "tests passed|tests failed" build-tsan/ctest.log | tail -n 1
  ((rc == 0)) || { grep -E "WARNING: ThreadSanitizer|Failed" build-tsan/ctest.log | head -n 30; die "ctest under TSan failed (build-tsan/ctest.log)"; }
  say "done"
  ;;
fuzz)
  SECS="${SECONDS_ARG:-20}"
  configure build-fuzz "address,undefined,fuzzer-no-link" "test_smoke" -DMATRIXTREE_FUZZ=ON
  mapfile -t HARNESSES < <(cd tests/fuzz && ls fuzz_*.cpp | sed 's/\.cpp$//')
  say "build (${HARNESSES[*]})"
  build build-fuzz "${HARNESSES[@]}"
  mkdir -p build-fuzz/findings
  failed=0
  for h in "${HARNESSES[@]}"; do
    corpus="build-fuzz/corpus/$h"
    mkdir -p "$corpus"
    regressions="tests/fuzz/regressions/$h"
    # A harness without regression inputs yet has no folder (git keeps no empty ones).
    inputs=("$corpus")
    [[ -d "$regressions" ]] && inputs+=("$regressions")
    # Replay the regressions (-runs=0 runs each given input once), then fuzz from seed 1.
    if [[ -d "$regressions" ]] &&
      ! ASAN_OPTIONS="detect_leaks=1" build-fuzz/bin/"$h" -runs=0 "$regressions" >"build-fuzz/$h.replay.log" 2>&1; then
      tail -n 20 "build-fuzz/$h.replay.log"
      failed=1
      say "$h: a regression input fails (build-fuzz/$h.replay.log)"
      continue
    fi
    ASAN_OPTIONS="detect_leaks=1" build-fuzz/bin/"$h" -seed=1 -max_total_time="$SECS" -timeout=20 -rss_limit_mb=4096 \
      -max_len=4096 -print_final_stats=1 -artifact_prefix="build-fuzz/findings/$h-" "${inputs[@]}" \
      >"build-fuzz/$h.log" 2>&1
    rc=$?
    runs="$(grep -Eo 'stat::number_of_executed_units: *[0-9]+' "build-fuzz/$h.log" | grep -Eo '[0-9]+$' || echo '?')"
    if ((rc != 0)); then
      failed=1
      grep -E "fuzz invariant|ERROR:|runtime error|SUMMARY" "build-fuzz/$h.log" | head -n 10
      say "$h: FINDING after $runs runs (input in build-fuzz/findings/; keep it in $regressions/ with the fix)"
    else
      say "$h: $runs runs in ${SECS} s, no finding"
    fi
  done
  say "Python reader fuzzer, ${SECS} s (tests/fuzz/fuzz_readers.py)"
  "$VPY" tests/fuzz/fuzz_readers.py --seconds "$SECS" --seed 1 --findings build-fuzz/findings || failed=1
  ((failed == 0)) || die "fuzzing found a failure (inputs in build-fuzz/findings/)"
  say "done"
  ;;
*)
  sed -n '2,16p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  exit 2
  ;;
esac

#!/usr/bin/env bash
# Sanitizer and fuzzing stages (docs/reliability.md), each in its own build folder. Needs
# scripts/setup.sh first (VTK, GoogleTest, .venv).
#
#   scripts/sanitize.sh asan             build-asan/ (GCC): the engine, the VTK 9.1 cell mirror, the
#                                        VTK module's library and a test subset under ASan+UBSan
#                                        against Debian's uninstrumented VTK; runs that ctest subset
#   scripts/sanitize.sh tsan             build-tsan/ (clang, LLVM's OpenMP with its Archer tool):
#                                        the threaded tests (std::thread and OpenMP) under TSan
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
# clang, compiler-rt and LLVM's OpenMP runtime (Debian 12: clang 14) for tsan and fuzz; asan uses
# the system GCC, whose libasan/libubsan come with g++.
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
ARCHER="$(dirname "$("$CXX_BIN" -print-file-name=libomp.so)")/libarcher.so"
[[ -f "$ARCHER" ]] || ARCHER="/usr/lib/llvm-14/lib/libarcher.so"
VPY="$ROOT/.venv/bin/python"
[[ -x "$VPY" ]] || die ".venv missing: run scripts/setup.sh first"

# configure DIR CC CXX SANITIZERS TESTS [extra cmake args]: a Debug-like -O1 -g build (assertions
# on). A folder configured with another compiler is emptied first (CMake cannot switch compilers).
configure() {
  local dir="$1" cc="$2" cxx="$3" sanitize="$4" tests="$5"
  shift 5
  if [[ -f "$ROOT/$dir/CMakeCache.txt" ]] &&
    ! grep -qx "CMAKE_CXX_COMPILER:[A-Z]*=$cxx" "$ROOT/$dir/CMakeCache.txt"; then
    rm -rf "${ROOT:?}/$dir"
  fi
  mkdir -p "$ROOT/$dir"
  cmake -S "$ROOT" -B "$ROOT/$dir" -DCMAKE_C_COMPILER="$cc" -DCMAKE_CXX_COMPILER="$cxx" \
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

GCC_BIN="$(command -v gcc)"
GXX_BIN="$(command -v g++)"

# The C++ subset under ASan+UBSan: every engine area (builders and their parallel primitives,
# trees, cells and the VTK 9.1 cell mirror with the locator core, rays and the batch tracers'
# leaf tests, the volume build and marcher) and the VTK classes' input checks and threaded
# queries, with the programs' slow real-mesh sweeps left to the normal build (ctest -E below).
ASAN_TESTS="test_input_checks;test_concurrency;test_cell_mirror;test_leaf_boxes;test_tree_queries;test_matrix_tree;test_build_sort;test_cells;test_cell_eval;test_edge_cases;test_parallel;test_rays;test_volume;test_block_sparse;test_layout;test_smoke"
# Also left out: the fuzz harnesses' ctest entries (their programs are the fuzz stage's) and the
# checks on the normal build's AVX2 objects (instrumented objects carry the sanitizer's symbols).
ASAN_EXCLUDE='RealMesh|Real/|AllMeshes|turbineblade|lucy|nefertiti|horse|bunny|Large|Huge|Sweep|^fuzz\.|avx2_unit_defines|VolumeAvx2\.'
# The threaded tests under TSan: queries from std::threads (test_concurrency), the OpenMP scan and
# radix sort (test_parallel), the OpenMP batch leaf tests (test_leaf_boxes), the OpenMP volume
# build, classification and render (test_volume).
TSAN_TESTS="test_concurrency;test_parallel;test_leaf_boxes;test_volume"
TSAN_EXCLUDE="$ASAN_EXCLUDE"

# run_ctest DIR EXCLUDE WHAT: ctest in DIR without the tests matching EXCLUDE; on failure print the
# sanitizer reports and stop.
run_ctest() {
  local dir="$1" exclude="$2" what="$3" rc
  ctest --test-dir "$dir" -j"$JOBS" --output-on-failure -E "$exclude" >"$dir/ctest.log" 2>&1
  rc=$?
  grep -E "tests passed|tests failed" "$dir/ctest.log" | tail -n 1
  ((rc == 0)) || {
    grep -E "ERROR: AddressSanitizer|WARNING: ThreadSanitizer|runtime error|SUMMARY|Failed|\*\*\*" "$dir/ctest.log" | head -n 30
    die "ctest under $what failed ($dir/ctest.log)"
  }
}

case "$STAGE" in
asan)
  configure build-asan "$GCC_BIN" "$GXX_BIN" "address,undefined" "$ASAN_TESTS"
  say "build with $("$GXX_BIN" -dumpfullversion) (engine, cell mirror, VTK module library, ${ASAN_TESTS//;/ })"
  build build-asan ${ASAN_TESTS//;/ }
  say "ctest (ASan+UBSan, leaks checked), excluding the real-mesh sweeps: /$ASAN_EXCLUDE/"
  ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:halt_on_error=1" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
    run_ctest build-asan "$ASAN_EXCLUDE" "ASan+UBSan"
  say "done"
  ;;
tsan)
  configure build-tsan "$CC_BIN" "$CXX_BIN" "thread" "$TSAN_TESTS"
  say "build with clang $("$CXX_BIN" -dumpversion) (${TSAN_TESTS//;/ })"
  build build-tsan ${TSAN_TESTS//;/ }
  # Archer (an OMPT tool of LLVM's OpenMP runtime) tells TSan about OpenMP's barriers, tasks and
  # reductions, so that only races between a region's threads are reported; Archer asks for
  # ignore_noninstrumented_modules=1, which skips the runtime's own (uninstrumented) accesses and
  # those inside Debian's VTK libraries, never the project's code.
  say "ctest under TSan (OpenMP through Archer: $ARCHER), excluding /$TSAN_EXCLUDE/"
  OMP_TOOL_LIBRARIES="$ARCHER" ARCHER_OPTIONS="verbose=0" TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:ignore_noninstrumented_modules=1" \
    run_ctest build-tsan "$TSAN_EXCLUDE" "TSan"
  say "done"
  ;;
fuzz)
  SECS="${SECONDS_ARG:-20}"
  configure build-fuzz "$CC_BIN" "$CXX_BIN" "address,undefined,fuzzer-no-link" "test_smoke" -DMATRIXTREE_FUZZ=ON
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

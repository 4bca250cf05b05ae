# The batch tracers' AVX2 unit (engine/src/rays/batch_trace_avx2.cpp) is the one file compiled with
# -mavx2. Every function it defines out of line must be its own (namespace mtree::batch_avx2, or a
# template instantiated on that namespace's types): an inline function of a shared header emitted
# there, compiled for AVX2, could be the copy the linker keeps for the whole program, and crash a
# CPU without AVX2. Run by ctest (test avx2_unit_defines_only_its_own_symbols) with
#   -DNM=<nm> -DOBJECTS=<the engine's object files, separated by |>
string(REPLACE "|" ";" objects "${OBJECTS}")
set(unit "")
foreach (o IN LISTS objects)
  if (o MATCHES "batch_trace_avx2")
    set(unit "${o}")
  endif ()
endforeach ()
if (unit STREQUAL "")
  message(FATAL_ERROR "no batch_trace_avx2 object among the engine's objects")
endif ()
execute_process(COMMAND "${NM}" -C --defined-only "${unit}" OUTPUT_VARIABLE out RESULT_VARIABLE rc)
if (NOT rc EQUAL 0)
  message(FATAL_ERROR "${NM} failed on ${unit}")
endif ()
string(REPLACE "\n" ";" lines "${out}")
set(bad "")
set(own 0)
foreach (line IN LISTS lines)
  # Global (T), weak (W, V) and unique (u) definitions are the ones another unit may share.
  if (line MATCHES "^[0-9a-fA-F]+ [TWVu] ")
    if (line MATCHES "mtree::batch_avx2::")
      math(EXPR own "${own} + 1")
    else ()
      string(APPEND bad "\n  ${line}")
    endif ()
  endif ()
endforeach ()
if (NOT bad STREQUAL "")
  message(FATAL_ERROR "the AVX2 unit defines shared symbols (make them MT_ALWAYS_INLINE, or keep the code that "
                      "needs them out of the AVX2 unit):${bad}")
endif ()
if (own EQUAL 0)
  message(FATAL_ERROR "the AVX2 unit defines no symbol of its own: it was not compiled as expected")
endif ()
message(STATUS "AVX2 unit: ${own} symbols, all in mtree::batch_avx2")

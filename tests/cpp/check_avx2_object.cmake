# Run by ctest (tests/cpp/CMakeLists.txt: VolumeAvx2.ObjectSharesNoCode) as
#   cmake -DNM=<nm> -DLIBRARY=<libmtengine.a> -P check_avx2_object.cmake
# Fails when the AVX2-compiled member march_avx2.cpp.o of the engine library defines a weak
# function symbol ("W"): an inline function whose copy the linker may keep for callers in the
# other, baseline-compiled files. Its own code must be in unnamed namespaces ("t": local).
execute_process(COMMAND "${NM}" -C "${LIBRARY}" OUTPUT_VARIABLE listing RESULT_VARIABLE rc)
if (NOT rc EQUAL 0)
  message(FATAL_ERROR "${NM} ${LIBRARY} failed (${rc})")
endif ()
string(REPLACE "\n" ";" lines "${listing}")
set(inside FALSE)
set(found FALSE)
set(weak "")
foreach (line IN LISTS lines)
  if (line MATCHES "^march_avx2\\.cpp\\.o:$")
    set(inside TRUE)
    set(found TRUE)
  elseif (line MATCHES "^[^ ]+\\.o:$")
    set(inside FALSE)
  elseif (inside AND line MATCHES "^[0-9a-f]* +W +(.*)$")
    string(APPEND weak "  ${CMAKE_MATCH_1}\n")
  endif ()
endforeach ()
if (NOT found)
  message(FATAL_ERROR "${LIBRARY} has no member march_avx2.cpp.o")
endif ()
if (weak)
  message(FATAL_ERROR "march_avx2.cpp.o (compiled for AVX2) defines shared inline functions:\n${weak}"
    "use the unnamed-namespace helpers of engine/src/volume/march.h instead")
endif ()
message(STATUS "march_avx2.cpp.o defines no shared inline function")

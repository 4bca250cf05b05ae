# Build type and compiler flags of every MatrixTree target, shared by the top-level build and
# python/bindings (the engine extension `pip install .` builds): include() after project().
get_property(_mt_multi_config GLOBAL PROPERTY GENERATOR_IS_MULTI_CONFIG)
if (NOT _mt_multi_config AND NOT CMAKE_BUILD_TYPE)
  set(CMAKE_BUILD_TYPE Release CACHE STRING "Build type" FORCE)
  set_property(CACHE CMAKE_BUILD_TYPE PROPERTY STRINGS
    Debug Release RelWithDebInfo MinSizeRel)
endif ()

set(CMAKE_CXX_STANDARD 17)
set(CMAKE_CXX_STANDARD_REQUIRED ON)
set(CMAKE_CXX_EXTENSIONS OFF)
set(CMAKE_EXPORT_COMPILE_COMMANDS ON)

# Release means -O3 (GCC/Clang default to it already; say it explicitly so a
# toolchain file cannot quietly lower it). No -march: binaries stay portable.
if (CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
  set(CMAKE_CXX_FLAGS_RELEASE "-O3 -DNDEBUG")
endif ()

# Warnings go on our own targets only, not on the code that VTK's wrappers
# generate (that code is not ours to fix). No -Wpedantic: it flags the
# customary `vtkTypeMacro(...);` (extra semicolon) in every VTK class.
set(MATRIXTREE_WARNING_FLAGS "")
if (CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
  set(MATRIXTREE_WARNING_FLAGS -Wall -Wextra)
elseif (MSVC)
  set(MATRIXTREE_WARNING_FLAGS /W4)
endif ()
function (matrixtree_set_warnings target)
  target_compile_options(${target} PRIVATE
    $<$<COMPILE_LANGUAGE:CXX>:${MATRIXTREE_WARNING_FLAGS}>)
endfunction ()

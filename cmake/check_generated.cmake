# Regenerates every example into a scratch directory and compares it with the committed
# generated/ tree (as SymForce's compare_or_update_directory does). Fails with the command
# that refreshes the committed copy.
#   cmake -DKINEGEN=... -DEXAMPLES=... -DGENERATED=... -DSCRATCH=... -P check_generated.cmake
file(REMOVE_RECURSE "${SCRATCH}")
file(MAKE_DIRECTORY "${SCRATCH}")
file(GLOB mechanisms "${EXAMPLES}/*.yaml" "${EXAMPLES}/*/*.yaml")
# Spatial examples are not committed as headers yet (their headers are 140-550 kB, and the strict
# compile of each would lengthen CI); the spatial test files are generated and strict-compiled
# by the tests (tests/CMakeLists.txt).
list(FILTER mechanisms EXCLUDE REGEX "/spatial/[^/]*\\.yaml$")
set(stale "")
foreach(mech IN LISTS mechanisms)
  execute_process(COMMAND "${KINEGEN}" generate "${mech}" -o "${SCRATCH}"
                  RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "kinegen generate ${mech} failed (${rc}): ${err}")
  endif()
endforeach()
file(GLOB fresh RELATIVE "${SCRATCH}" "${SCRATCH}/*.hpp")
file(GLOB committed RELATIVE "${GENERATED}" "${GENERATED}/*.hpp")
foreach(h IN LISTS fresh committed)
  if(NOT EXISTS "${GENERATED}/${h}" OR NOT EXISTS "${SCRATCH}/${h}")
    list(APPEND stale "${h}")
    continue()
  endif()
  file(READ "${GENERATED}/${h}" a)
  file(READ "${SCRATCH}/${h}" b)
  if(NOT a STREQUAL b)
    list(APPEND stale "${h}")
  endif()
endforeach()
list(REMOVE_DUPLICATES stale)
if(stale)
  message(FATAL_ERROR "generated/ is stale: ${stale}\n"
                      "Refresh it with: scripts/update_generated.sh")
endif()
message(STATUS "generated/ is up to date (${fresh})")

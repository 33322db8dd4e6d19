# Installs kinegen into a fresh prefix, builds the consumer project in tests/consumer against it
# with find_package(kinegen), runs it, then edits the mechanism file and checks that the build
# regenerates the header and the program sees the change.
#
# cmake -DKINEGEN_BUILD=<build dir> -DCONSUMER_SOURCE=<tests/consumer> -DMECHANISM=<yaml>
#       -DWORK=<scratch dir> -DGENERATOR=<generator> -P run_consumer_test.cmake
foreach(var KINEGEN_BUILD CONSUMER_SOURCE MECHANISM WORK GENERATOR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "${var} is not set")
  endif()
endforeach()

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  set(out "${out}" PARENT_SCOPE)
endfunction()

function(expect_output expected)
  run(${WORK}/build/consumer)
  if(NOT out MATCHES "slider x at t = 0.5: ${expected}")
    message(FATAL_ERROR "consumer printed '${out}', expected slider x = ${expected}")
  endif()
  message(STATUS "consumer: ${out}")
endfunction()

file(REMOVE_RECURSE ${WORK})
set(prefix ${WORK}/prefix)
run(${CMAKE_COMMAND} --install ${KINEGEN_BUILD} --prefix ${prefix})
foreach(f bin/kinegen include/kinegen/solver.hpp lib/cmake/kinegen/kinegenConfig.cmake
          lib/cmake/kinegen/kinegen_add_model.cmake)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "not installed: ${f}")
  endif()
endforeach()

# The project as a user has it: its sources and its own copy of the mechanism.
file(COPY ${CONSUMER_SOURCE}/CMakeLists.txt ${CONSUMER_SOURCE}/main.cpp DESTINATION ${WORK}/src)
configure_file(${MECHANISM} ${WORK}/src/mechanism.yaml COPYONLY)

run(${CMAKE_COMMAND} -S ${WORK}/src -B ${WORK}/build -G ${GENERATOR}
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${prefix})
if(NOT out MATCHES "kinegen executable: ${prefix}/bin/kinegen")
  message(FATAL_ERROR "the consumer did not use the installed kinegen:\n${out}")
endif()
run(${CMAKE_COMMAND} --build ${WORK}/build)
set(header ${WORK}/build/kinegen/consumer/slider_crank.hpp)
if(NOT EXISTS ${header})
  message(FATAL_ERROR "no generated header at ${header}")
endif()
# Closed form: x = cos(0.5) + sqrt(l^2 - sin(0.5)^2) with l = 2.
expect_output("2.819270269")

# The header as first generated.
file(SHA256 ${header} hash_before)

# Edit the mechanism: a longer rod (l = 2.5). Sleep so the edit is visibly newer.
execute_process(COMMAND ${CMAKE_COMMAND} -E sleep 1.1)
file(READ ${WORK}/src/mechanism.yaml text)
string(REGEX REPLACE "\n  l: 2.0" "\n  l: 2.5" edited "${text}")
if(edited STREQUAL text)
  message(FATAL_ERROR "could not edit the rod length in ${MECHANISM}")
endif()
file(WRITE ${WORK}/src/mechanism.yaml "${edited}")
run(${CMAKE_COMMAND} --build ${WORK}/build)
file(SHA256 ${header} hash_after)
if(hash_after STREQUAL hash_before)
  message(FATAL_ERROR "the header was not regenerated after the mechanism changed")
endif()
# Closed form with l = 2.5.
expect_output("3.331182194")
message(STATUS "consumer project: built against the installed package, regenerated on edit")

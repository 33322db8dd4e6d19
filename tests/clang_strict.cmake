# The strict instantiations (tests/CMakeLists.txt) under Clang's warnings, syntax only: Clang's
# -Wshadow also sees a kernel's parameter shadowing a header's static member, which GCC's does
# not, and users compile the headers with either.
#   cmake -DCLANGXX=clang++ -DDIR=<build>/tests/strict -DINCLUDES=<runtime/include>
#         -DSYSTEM=<Eigen's> -P clang_strict.cmake
file(GLOB sources ${DIR}/*.cpp)
list(LENGTH sources count)
if(count EQUAL 0)
  message(FATAL_ERROR "no strict instantiations in ${DIR}: nothing to check")
endif()
set(flags -std=c++17 -fsyntax-only -Wall -Wextra -Wpedantic -Wshadow -Werror)
foreach(dir IN LISTS INCLUDES)
  list(APPEND flags -I${dir})
endforeach()
foreach(dir IN LISTS SYSTEM)
  list(APPEND flags -isystem ${dir})
endforeach()
set(failed "")
foreach(source IN LISTS sources)
  execute_process(COMMAND ${CLANGXX} ${flags} ${source} RESULT_VARIABLE rc ERROR_VARIABLE err
                  OUTPUT_QUIET)
  if(NOT rc EQUAL 0)
    message("${err}")
    list(APPEND failed ${source})
  endif()
endforeach()
if(failed)
  message(FATAL_ERROR "clang++ warns on: ${failed}")
endif()
message("clang++ -Wall -Wextra -Wpedantic -Wshadow: ${count} instantiations clean")

# kinegen_unity(TARGET SIZE n [ALONE file...]): with KINEGEN_UNITY_BUILD on, compiles TARGET's
# .cpp files `n` to a unit (CMake's unity build, group mode: most of a file's compile time is
# the GiNaC, Eigen and CLI11 templates that every file of a unit then shares). The files named
# after ALONE compile on their own: they define a name in an anonymous namespace that another
# file defines too (the constraint files' `equations` and `draw`, by design), or GCC warns about
# them once included by a unit's source. Units follow the order of the target's sources, so a
# new file shifts the units after it: a clash then shows as a compile error, except between
# overloads, which is why same-named helpers of different files must differ in their arity (the
# command line's write_json, write_text and write_csv do) or stay apart.
function(kinegen_unity target)
  if(NOT KINEGEN_UNITY_BUILD)
    return()
  endif()
  cmake_parse_arguments(PARSE_ARGV 1 arg "" "SIZE" "ALONE")
  set(alone "")
  foreach(f IN LISTS arg_ALONE)
    get_filename_component(f "${f}" ABSOLUTE)
    list(APPEND alone "${f}")
  endforeach()
  get_target_property(sources ${target} SOURCES)
  set(i 0)
  foreach(f IN LISTS sources)
    get_filename_component(path "${f}" ABSOLUTE)
    if(NOT path MATCHES "\\.cpp$" OR path IN_LIST alone)
      continue()
    endif()
    math(EXPR group "${i} / ${arg_SIZE}")
    set_source_files_properties("${f}" PROPERTIES UNITY_GROUP "${target}_${group}")
    math(EXPR i "${i} + 1")
  endforeach()
  set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_MODE GROUP)
endfunction()

# kinegen_add_model(TARGET <target> MODEL <mechanism.yaml>
#                   [NAME <name>] [OUTPUT_DIR <dir>] [OUTPUTS <what>...]
#                   [PARAMS <name>=<value>...] [FOLD_PARAMS])
#
# Generates <name>.hpp from the mechanism file at build time and makes <target> depend on it:
# the header is regenerated when the mechanism file (or the kinegen executable) changes, and
# <dir> is added to the target's include path, so `#include "<name>.hpp"` works.
#
#   NAME        the mechanism's `name:` (the header's file name); read from the file if omitted,
#               in which case a change of the file re-runs CMake's configure step.
#   OUTPUT_DIR  where the header goes; default ${CMAKE_CURRENT_BINARY_DIR}/kinegen/<target>.
#   OUTPUTS     passed on as `--outputs a,b` (what the header should contain, where the kinegen
#               in use supports it); nothing is passed when omitted.
#   PARAMS      passed on as `--param name=value` each.
#   FOLD_PARAMS passes `--fold-params`: parameter values become constants in the code.
#
# The generated header needs only the C++ standard library. To solve with it, link the
# runtime as well: target_link_libraries(<target> PRIVATE kinegen::runtime).
include_guard(GLOBAL)

function(kinegen_add_model)
  cmake_parse_arguments(PARSE_ARGV 0 KG "FOLD_PARAMS" "TARGET;MODEL;NAME;OUTPUT_DIR"
                        "OUTPUTS;PARAMS")
  if(KG_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "kinegen_add_model: unknown arguments: ${KG_UNPARSED_ARGUMENTS}")
  endif()
  if(NOT KG_TARGET OR NOT KG_MODEL)
    message(FATAL_ERROR "kinegen_add_model: TARGET and MODEL are required")
  endif()
  if(NOT TARGET ${KG_TARGET})
    message(FATAL_ERROR "kinegen_add_model: '${KG_TARGET}' is not a target")
  endif()
  if(NOT TARGET kinegen::kinegen)
    message(FATAL_ERROR "kinegen_add_model: the kinegen::kinegen executable is not known; "
                        "call find_package(kinegen) first")
  endif()
  get_filename_component(model "${KG_MODEL}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
  if(NOT EXISTS "${model}")
    message(FATAL_ERROR "kinegen_add_model: no mechanism file '${model}'")
  endif()

  set(name "${KG_NAME}")
  if(NOT name)
    file(STRINGS "${model}" name_line REGEX "^name:[ \t]*[A-Za-z_][A-Za-z0-9_]*" LIMIT_COUNT 1)
    string(REGEX REPLACE "^name:[ \t]*([A-Za-z_][A-Za-z0-9_]*).*$" "\\1" name "${name_line}")
    if(NOT name)
      message(FATAL_ERROR "kinegen_add_model: no top-level 'name:' in ${model}; pass NAME")
    endif()
    # The header's name comes from the file: re-read it when the file changes.
    set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${model}")
  endif()

  set(dir "${KG_OUTPUT_DIR}")
  if(NOT dir)
    set(dir "${CMAKE_CURRENT_BINARY_DIR}/kinegen/${KG_TARGET}")
  endif()
  get_filename_component(dir "${dir}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_BINARY_DIR}")
  set(header "${dir}/${name}.hpp")

  set(args generate "${model}" -o "${dir}" --quiet)
  foreach(p IN LISTS KG_PARAMS)
    list(APPEND args --param "${p}")
  endforeach()
  if(KG_FOLD_PARAMS)
    list(APPEND args --fold-params)
  endif()
  if(KG_OUTPUTS)
    list(JOIN KG_OUTPUTS "," outputs)
    list(APPEND args --outputs "${outputs}")
  endif()

  add_custom_command(
    OUTPUT "${header}"
    COMMAND kinegen::kinegen ${args}
    DEPENDS "${model}" "$<TARGET_FILE:kinegen::kinegen>"
    COMMENT "kinegen: generating ${name}.hpp from ${KG_MODEL}"
    VERBATIM)
  # A target of its own, so the header is made once even if several targets use it, and
  # before any of <target>'s sources compile.
  set(gen_target "kinegen_generate_${KG_TARGET}_${name}")
  add_custom_target(${gen_target} DEPENDS "${header}")
  add_dependencies(${KG_TARGET} ${gen_target})
  target_include_directories(${KG_TARGET} PRIVATE "${dir}")
endfunction()

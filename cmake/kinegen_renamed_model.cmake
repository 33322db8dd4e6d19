# kinegen_renamed_model(<source.yaml> <new_name> <out_var>): a copy of a mechanism file in the
# build tree whose `name:` is <new_name>, so that two variants of one model (say, with and
# without folded parameters) can live in one program. For the project's own tests and
# benchmarks; the copy is refreshed when the source changes.
include_guard(GLOBAL)

function(kinegen_renamed_model source new_name out_var)
  file(READ "${source}" text)
  string(REGEX REPLACE "(^|\n)name:[ \t]*[A-Za-z_][A-Za-z0-9_]*" "\\1name: ${new_name}" text
         "${text}")
  set(dir "${CMAKE_CURRENT_BINARY_DIR}/renamed_models")
  file(WRITE "${dir}/${new_name}.yaml.tmp" "${text}")
  file(COPY_FILE "${dir}/${new_name}.yaml.tmp" "${dir}/${new_name}.yaml" ONLY_IF_DIFFERENT)
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${source}")
  set(${out_var} "${dir}/${new_name}.yaml" PARENT_SCOPE)
endfunction()

# `kinegen view`'s page, embedded in the generator library (codegen/CMakeLists.txt includes
# this after kinegen_codegen). With KINEGEN_BUILD_VIEWER (top-level option, on by default) the
# page's sources in viewer/, uPlot and three.js, at the versions viewer/package-lock.json pins and
# installed in viewer/node_modules by `npm ci` (scripts/setup.sh), become
# embedded/kinegen/codegen/io/viewer_assets.hpp. Without it nothing here needs node or npm, and
# `kinegen view` says the build has no viewer.
set(kinegen_viewer_dir ${PROJECT_SOURCE_DIR}/viewer)
if(KINEGEN_BUILD_VIEWER)
  set(kinegen_uplot_dir ${kinegen_viewer_dir}/node_modules/uplot)
  set(kinegen_three_dir ${kinegen_viewer_dir}/node_modules/three)
  file(READ ${kinegen_viewer_dir}/package-lock.json kinegen_lock)
  # uPlot (every page) and three.js (spatial runs' pages), at the versions the lock file pins.
  foreach(kinegen_package uplot three)
    string(JSON kinegen_pinned GET "${kinegen_lock}" packages node_modules/${kinegen_package}
           version)
    set(kinegen_package_dir ${kinegen_viewer_dir}/node_modules/${kinegen_package})
    if(NOT EXISTS ${kinegen_package_dir}/package.json)
      message(FATAL_ERROR "The viewer (KINEGEN_BUILD_VIEWER) inlines ${kinegen_package} "
                          "${kinegen_pinned} from viewer/node_modules: run `npm ci` in viewer/ "
                          "(scripts/setup.sh does), or configure with -DKINEGEN_BUILD_VIEWER=OFF")
    endif()
    file(READ ${kinegen_package_dir}/package.json kinegen_package_json)
    string(JSON kinegen_installed GET "${kinegen_package_json}" version)
    if(NOT kinegen_installed STREQUAL kinegen_pinned)
      message(FATAL_ERROR "viewer/node_modules has ${kinegen_package} ${kinegen_installed} where "
                          "viewer/package-lock.json pins ${kinegen_pinned}: run `npm ci` in viewer/")
    endif()
    set(kinegen_${kinegen_package}_installed ${kinegen_installed})
  endforeach()
  set(kinegen_viewer_assets
      ${CMAKE_CURRENT_BINARY_DIR}/embedded/kinegen/codegen/io/viewer_assets.hpp)
  add_custom_command(
    OUTPUT ${kinegen_viewer_assets}
    COMMAND ${CMAKE_COMMAND} -DVIEWER_DIR=${kinegen_viewer_dir} -DUPLOT_DIR=${kinegen_uplot_dir}
            -DTHREE_DIR=${kinegen_three_dir} -DOUTPUT=${kinegen_viewer_assets}
            -P ${PROJECT_SOURCE_DIR}/cmake/embed_viewer.cmake
    DEPENDS ${kinegen_viewer_dir}/page.html ${kinegen_viewer_dir}/view.css
            ${kinegen_viewer_dir}/drawing.js ${kinegen_viewer_dir}/view.js
            ${kinegen_uplot_dir}/package.json
            ${kinegen_uplot_dir}/dist/uPlot.iife.min.js ${kinegen_uplot_dir}/dist/uPlot.min.css
            ${kinegen_viewer_dir}/space.html ${kinegen_viewer_dir}/space.js
            ${kinegen_three_dir}/package.json ${kinegen_three_dir}/build/three.core.min.js
            ${kinegen_three_dir}/build/three.module.min.js
            ${kinegen_three_dir}/examples/jsm/controls/OrbitControls.js
            ${PROJECT_SOURCE_DIR}/cmake/embed_viewer.cmake
    COMMENT "Embedding the viewer page (uPlot ${kinegen_uplot_installed}, three.js ${kinegen_three_installed})"
    VERBATIM)
  target_sources(kinegen_codegen PRIVATE ${kinegen_viewer_assets})
  # The run's data is deflated in the page (the browser inflates it: DecompressionStream).
  find_package(ZLIB REQUIRED)
  target_link_libraries(kinegen_codegen PRIVATE ZLIB::ZLIB)
  set_source_files_properties(src/io/view_page.cpp PROPERTIES
                              COMPILE_DEFINITIONS KINEGEN_HAVE_VIEWER
                              OBJECT_DEPENDS ${kinegen_viewer_assets})
else()
  message(STATUS "kinegen view off (KINEGEN_BUILD_VIEWER=OFF): `kinegen view` reports that")
endif()

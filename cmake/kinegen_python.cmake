# Finds what the Python module (python/) needs and sets the option KINEGEN_BUILD_PYTHON: on
# by default when pybind11 and a Python with numpy are found, off under sanitizers.
# When the first interpreter on PATH lacks numpy, /usr/bin/python3 is tried; choose another with
# -DPython3_EXECUTABLE=...
set(kinegen_python_given OFF)
if(DEFINED CACHE{Python3_EXECUTABLE})
  set(kinegen_python_given ON)
endif()
find_package(Python3 COMPONENTS Interpreter Development.Module NumPy QUIET)
if(NOT Python3_FOUND AND NOT kinegen_python_given AND EXISTS /usr/bin/python3)
  # The first interpreter on PATH lacks numpy (pyenv, a virtualenv): try the system's, which
  # the Debian packages serve.
  foreach(cached _Python3_EXECUTABLE _Python3_INCLUDE_DIR _Python3_NumPy_INCLUDE_DIR
                 _Python3_INTERPRETER_SIGNATURE _Python3_DEVELOPMENT_MODULE_SIGNATURE)
    unset(${cached} CACHE)
  endforeach()
  set(Python3_EXECUTABLE /usr/bin/python3)
  find_package(Python3 COMPONENTS Interpreter Development.Module NumPy QUIET)
endif()
if(Python3_FOUND)
  # Only then: without a Python it can use, pybind11's own search fails the configure.
  find_package(pybind11 CONFIG QUIET)
endif()
if(CMAKE_CXX_FLAGS MATCHES "-fsanitize")
  # python3 does not load the sanitizer runtime first, so an instrumented module cannot load.
  set(kinegen_python_default OFF)
  message(STATUS "Python module off: sanitizer build (scripts/sanitize.sh)")
elseif(pybind11_FOUND AND Python3_FOUND)
  set(kinegen_python_default ON)
else()
  set(kinegen_python_default OFF)
  message(STATUS "Python module off: needs pybind11 and numpy for ${Python3_EXECUTABLE} "
                 "(another interpreter: -DPython3_EXECUTABLE=/usr/bin/python3)")
endif()
option(KINEGEN_BUILD_PYTHON "Build the Python module kinegen (pybind11, numpy)"
       ${kinegen_python_default})

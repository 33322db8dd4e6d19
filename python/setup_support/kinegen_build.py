"""The build backend of `pip install .` (pyproject.toml): setuptools' own, found offline.

pip builds in an isolated environment and installs the build requirements there from the
package index. kinegen declares none, so that `pip install .` needs no network: this backend
uses the setuptools (and wheel) of the interpreter that runs pip (Debian's python3-setuptools
and python3-wheel), putting its site-packages back at the end of the path when the isolated
environment hides them. Everything else is setuptools.build_meta, driving setup.py, whose
build_ext runs the project's CMake build (cmake_build_ext.py).
"""
import site
import sys


def _setuptools():
    try:
        import setuptools.build_meta as backend
        return backend, False
    except ImportError:
        pass
    # The isolated environment has no setuptools: the interpreter's own, after everything else.
    for path in site.getsitepackages():
        if path not in sys.path:
            sys.path.append(path)
    try:
        import setuptools.build_meta as backend
        import wheel  # noqa: F401  setuptools' bdist_wheel (before 70.1) needs it
    except ImportError as e:
        raise ImportError(
            "building kinegen needs setuptools and wheel for this Python "
            f"({sys.executable}): apt-get install python3-setuptools python3-wheel, or pip "
            f"install setuptools wheel ({e})") from e
    return backend, True


_backend, _borrowed = _setuptools()


def get_requires_for_build_wheel(config_settings=None):
    # setuptools < 70.1 asks for `wheel`, which pip would fetch from the index.
    return [] if _borrowed else _backend.get_requires_for_build_wheel(config_settings)


def get_requires_for_build_sdist(config_settings=None):
    return [] if _borrowed else _backend.get_requires_for_build_sdist(config_settings)


prepare_metadata_for_build_wheel = _backend.prepare_metadata_for_build_wheel
build_wheel = _backend.build_wheel
build_sdist = _backend.build_sdist

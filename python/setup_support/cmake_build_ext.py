"""setup.py's build: the Python module kinegen from the project's own CMake build.

setuptools knows one extension, `kinegen`; build_ext configures the repository with CMake
(tests and benchmarks off, this interpreter as Python3_EXECUTABLE, ccache when present) in
build-pip-<python>/ at the repository's root, builds the target kinegen_python and copies the
module where setuptools packs it. The viewer (kinegen view's page, Mechanism.view) is built when
viewer/node_modules holds uPlot (`npm ci` in viewer/, scripts/setup.sh), or as
KINEGEN_BUILD_VIEWER=ON/OFF in the environment says. CMAKE_ARGS adds CMake options.
"""
import os
import pathlib
import re
import shlex
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


def version(source):
    text = (source / "CMakeLists.txt").read_text()
    return re.search(r"project\(kinegen VERSION ([0-9.]+)", text).group(1)


class CMakeBuild(build_ext):
    source = None

    def build_extension(self, ext):
        source = self.source
        tag = f"{sys.implementation.cache_tag}-{sys.platform}"
        build = source / f"build-pip-{tag}"  # beside build/: ccache (base_dir) hits the same objects
        viewer = os.environ.get("KINEGEN_BUILD_VIEWER")
        if viewer is None:
            viewer = "ON" if (source / "viewer/node_modules/uplot/package.json").exists() else "OFF"
            if viewer == "OFF":
                print("kinegen: viewer/node_modules has no uPlot (npm ci in viewer/): building "
                      "without the viewer (Mechanism.view says so)", file=sys.stderr)
        args = [f"-DPython3_EXECUTABLE={sys.executable}", "-DCMAKE_BUILD_TYPE=Release",
                "-DKINEGEN_BUILD_TESTS=OFF", "-DKINEGEN_BUILD_BENCHMARKS=OFF",
                "-DKINEGEN_BUILD_PYTHON=ON", f"-DKINEGEN_BUILD_VIEWER={viewer}"]
        if shutil.which("ccache"):
            args.append("-DCMAKE_CXX_COMPILER_LAUNCHER=ccache")
        args += shlex.split(os.environ.get("CMAKE_ARGS", ""))
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", str(os.cpu_count() or 1))
        # CMake asks the interpreter for numpy as a user runs it, not through pip's isolated
        # build environment (PYTHONPATH to a sitecustomize that hides site-packages).
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONNOUSERSITE")}
        # KINEGEN_CMAKE_BUILD_DIR: an existing, configured build tree to build the module in
        # (the pip_install test uses the suite's own build/, so it packages without compiling
        # the library a second time; a user's pip install configures build-pip-*/ itself).
        reuse = os.environ.get("KINEGEN_CMAKE_BUILD_DIR")
        if reuse:
            build = pathlib.Path(reuse)
        else:
            subprocess.run(["cmake", "-S", str(source), "-B", str(build), *args], check=True,
                           env=env)
        subprocess.run(["cmake", "--build", str(build), "--target", "kinegen_python", "-j", jobs],
                       check=True, env=env)
        suffix = pathlib.Path(self.get_ext_filename(ext.name)).name
        built = build / "python" / suffix
        if not built.exists():
            raise RuntimeError(f"CMake built no {built}")
        target = pathlib.Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(built, target)


def kinegen_setup(source):
    """setup() for the repository at `source` (setup.py at the root, or python/setup.py)."""
    source = pathlib.Path(source).resolve()
    CMakeBuild.source = source
    # setuptools' own files beside the CMake build, not in the source tree.
    work = source / "build-pip-setuptools"
    work.mkdir(exist_ok=True)
    setup(
        options={"egg_info": {"egg_base": os.path.relpath(work)},
                 "build": {"build_base": os.path.relpath(work)}},
        name="kinegen",
        version=version(source),
        description="Planar mechanism kinematics: from a mechanism file to analyses, pages "
                    "and generated C++",
        python_requires=">=3.9",
        install_requires=["numpy"],
        ext_modules=[Extension("kinegen", sources=[])],
        cmdclass={"build_ext": CMakeBuild},
        zip_safe=False,
    )

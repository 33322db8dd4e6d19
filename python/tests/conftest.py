import os
import pathlib
import subprocess

import numpy as np
import pytest

SOURCE = pathlib.Path(os.environ.get("KINEGEN_SOURCE_DIR", pathlib.Path(__file__).parents[2]))
EXE = os.environ.get("KINEGEN_EXE", str(SOURCE / "build" / "codegen" / "kinegen"))


def run(*args):
    # The command line, its output captured as text.
    return subprocess.run([EXE, *args], capture_output=True, text=True)


def read_csv(path):
    # A kinegen CSV: its header's names and its rows as an array.
    with open(path) as f:
        header = f.readline().rstrip("\n").split(",")
        rows = [[float(v) for v in line.rstrip("\n").split(",")] for line in f]
    return header, np.array(rows)


@pytest.fixture
def exe():
    return EXE


@pytest.fixture
def source():
    return SOURCE


def has_free_coordinates(path):
    # A top-level `free:` list; such mechanisms move under their forces (simulate),
    # and `analyze` refuses them without --input for each free item.
    return any(line.startswith("free:") for line in open(path))


def examples():
    # The single-file examples and those in folders (cams, forces, gears, slots, ...) that
    # `analyze` drives as they are: all but the free-motion ones (examples/dynamics) and the
    # spatial ones (examples/spatial), which test_spatial.py checks against the command line.
    return sorted(str(p) for pattern in ("*.yaml", "*/*.yaml")
                  for p in (SOURCE / "examples").glob(pattern)
                  if not has_free_coordinates(p) and p.parent.name != "spatial")

import os
import pathlib

import pytest

SOURCE = pathlib.Path(os.environ.get("KINEGEN_SOURCE_DIR", pathlib.Path(__file__).parents[2]))
EXE = os.environ.get("KINEGEN_EXE", str(SOURCE / "build" / "codegen" / "kinegen"))


@pytest.fixture
def exe():
    return EXE


@pytest.fixture
def source():
    return SOURCE


def examples():
    # The single-file examples and those in folders (cams, forces, gears, slots, ...).
    return sorted(str(p) for pattern in ("*.yaml", "*/*.yaml")
                  for p in (SOURCE / "examples").glob(pattern))

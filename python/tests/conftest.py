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
    return sorted(str(p) for p in (SOURCE / "examples").glob("*.yaml"))

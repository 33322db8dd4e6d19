"""pip install . from python/: the repository's build (setup_support/cmake_build_ext.py)."""
import pathlib
import sys

here = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(here / "setup_support"))
from cmake_build_ext import kinegen_setup  # noqa: E402

kinegen_setup(here.parent)

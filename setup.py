"""pip install . from the repository's root: python/setup_support/cmake_build_ext.py."""
import pathlib
import sys

root = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(root / "python" / "setup_support"))
from cmake_build_ext import kinegen_setup  # noqa: E402

kinegen_setup(root)

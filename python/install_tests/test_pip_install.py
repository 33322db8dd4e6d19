"""`pip install .` works as Python users expect, with no network: from the repository's root and
from python/, into a fresh virtual environment made with --system-site-packages (numpy and
setuptools from Debian). There the module imports from the environment and analyses exactly as
the command line does. A CMake build of its own (build-pip-*/ at the root): minutes, so it is a
test of its own (ctest -R pip_install), not part of the python test."""
import json
import os
import pathlib
import subprocess
import sys

SOURCE = pathlib.Path(os.environ.get("KINEGEN_SOURCE_DIR", pathlib.Path(__file__).parents[2]))
EXE = os.environ.get("KINEGEN_EXE", str(SOURCE / "build" / "codegen" / "kinegen"))
TURN = "6.283185307179586"

CHECK = """
import json, sys, kinegen
m = kinegen.Mechanism(sys.argv[1])
r = m.analyze(0, float(sys.argv[2]), 36)
print(json.dumps({"file": kinegen.__file__, "columns": list(r),
                  "values": {k: [float(v).hex() for v in r[k]] for k in r}}))
"""


def offline_env():
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    # No index, no machine pip configuration (find-links), no way out: pip must not need one.
    env.update(PIP_NO_INDEX="1", PIP_CONFIG_FILE=os.devnull, PIP_DISABLE_PIP_VERSION_CHECK="1",
               http_proxy="http://127.0.0.1:9", https_proxy="http://127.0.0.1:9")
    return env


def test_pip_install_offline_into_a_fresh_venv(tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    python = str(venv / "bin" / "python")
    csv = tmp_path / "four_bar.csv"
    four_bar = str(SOURCE / "examples" / "four_bar.yaml")
    r = subprocess.run([EXE, "analyze", four_bar, "--t0", "0", "--t1", TURN, "--steps", "36",
                        "-o", str(csv)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    lines = csv.read_text().splitlines()
    header = lines[0].split(",")
    rows = [[float(v) for v in line.split(",")] for line in lines[1:]]
    for where in (SOURCE, SOURCE / "python"):
        install = subprocess.run([python, "-m", "pip", "install", "."], cwd=where,
                                 env=offline_env(), capture_output=True, text=True)
        assert install.returncode == 0, install.stdout[-6000:] + install.stderr[-6000:]
        assert "Successfully installed kinegen" in install.stdout
        got = subprocess.run([python, "-c", CHECK, four_bar, TURN], cwd=tmp_path,
                             env=offline_env(), capture_output=True, text=True)
        assert got.returncode == 0, got.stderr
        result = json.loads(got.stdout)
        assert pathlib.Path(result["file"]).is_relative_to(venv), result["file"]
        assert result["columns"] == header
        for c, name in enumerate(header):  # bit for bit: the CSV's 17 digits read back
            assert result["values"][name] == [row[c].hex() for row in rows], name
        subprocess.run([python, "-m", "pip", "uninstall", "-y", "kinegen"], check=True,
                       env=offline_env(), capture_output=True)

"""Tables (issue 35, item 8): a process is no longer limited to 1000 of them."""
import pytest

import kinegen


def test_one_table_mechanism_loaded_many_times(tmp_path):
    # The 1001st load of a one-table mechanism (each earlier one deleted) failed with "more
    # than 1000 tables in one process", naming no file. Each load gets a table of its own
    # values (equal ones share one), and each answer is checked against its own table.
    (tmp_path / "m.yaml").write_text(
        "name: slide\n"
        "bodies:\n  - {name: block, q0: [0, 0, 0]}\n"
        "joints:\n  - {type: absolute_y, body: block, value: 0}\n"
        "  - {type: absolute_angle, body: block, value: 0}\n"
        "drivers:\n  - {type: absolute_x, body: block, table: x.csv}\n")
    for k in range(1100):
        # x(t) = c t on the table's knots: the spline reproduces it exactly.
        c = 1 + k * 1e-3
        (tmp_path / "x.csv").write_text(
            "t,value\n" + "\n".join("%d,%r" % (t, c * t) for t in range(5)) + "\n")
        m = kinegen.Mechanism(str(tmp_path / "m.yaml"))
        run = m.analyze(0, 4, 4)
        assert run["block.x"][2] == pytest.approx(2 * c, rel=1e-14), k
        del m

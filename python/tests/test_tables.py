"""Tables (issue 35, item 8) belong to their model: loading many, each deleted before the
next, holds only the live ones."""
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
    before = kinegen._live_tables()
    for k in range(1001):
        # x(t) = c t on the table's knots: the spline reproduces it exactly.
        c = 1 + k * 1e-3
        (tmp_path / "x.csv").write_text(
            "t,value\n" + "\n".join("%d,%r" % (t, c * t) for t in range(5)) + "\n")
        m = kinegen.Mechanism(str(tmp_path / "m.yaml"))
        # Only the live mechanism's table is held: the deleted ones' were freed with them.
        assert kinegen._live_tables() == before + 1, k
        run = m.analyze(0, 4, 4)
        assert run["block.x"][2] == pytest.approx(2 * c, rel=1e-14), k
        del m
    assert kinegen._live_tables() == before
    # Two live mechanisms with equal tables share one; the table outlives the first deleted.
    a = kinegen.Mechanism(str(tmp_path / "m.yaml"))
    b = kinegen.Mechanism(str(tmp_path / "m.yaml"))
    assert kinegen._live_tables() == before + 1
    del a
    assert b.analyze(0, 4, 4)["block.x"][4] == pytest.approx(4 * (1 + 1000e-3), rel=1e-14)
    del b
    assert kinegen._live_tables() == before

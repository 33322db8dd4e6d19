"""Python threads on the kinegen module (issue 28, item 1): THREADS threads for SECONDS seconds,
each mixing load, analyze, check, generate and eval on the examples, every result compared with
the one a single thread computed first. Prints one summary line and exits 0 when every result
matched; a crash (the module before its lock: SIGSEGV, "malloc(): unaligned tcache chunk") or a
hang (the caller's timeout) fails.

    python3 thread_stress.py [SECONDS] [THREADS]        (default 3 s, 8 threads)

python/tests/test_threads.py runs it briefly; a 60 s run is opt-in there
(KINEGEN_STRESS_SECONDS=60)."""
import os
import pathlib
import random
import sys
import tempfile
import threading
import time

import numpy as np

import kinegen

SOURCE = pathlib.Path(os.environ.get("KINEGEN_SOURCE_DIR", pathlib.Path(__file__).parents[2]))
FILES = [str(SOURCE / p) for p in ("examples/four_bar.yaml", "examples/slider_crank.yaml",
                                   "examples/gears/steering.yaml", "examples/cams/disc_cam.yaml")]
GRID = (0.0, 0.2, 4)


def reference(path, scratch):
    m = kinegen.Mechanism(path)
    header = pathlib.Path(m.generate(str(scratch / "alone"))).read_text()
    return {"analyze": m.analyze(*GRID), "eval": m.eval(t=0.3), "header": header,
            "name": m.name, "nq": m.nq}


def same(a, b):
    return list(a) == list(b) and all(np.array_equal(a[k], b[k]) for k in a)


def worker(index, refs, seconds, scratch, tally, failures):
    rng = random.Random(index)
    out = scratch / f"thread{index}"
    end = time.monotonic() + seconds
    models = {}
    while time.monotonic() < end:
        path = rng.choice(FILES)
        ref = refs[path]
        op = rng.choice(["load", "analyze", "check", "generate", "eval"])
        try:
            if op == "load" or path not in models:
                models[path] = kinegen.Mechanism(path)  # the old one is destroyed here
                ok = models[path].name == ref["name"] and models[path].nq == ref["nq"]
            m = models[path]
            # A fresh model's first analysis derives its block structure (GiNaC): the old module
            # did that with the GIL released, beside other threads' GiNaC work.
            if op == "load" or op == "analyze":
                ok = same(m.analyze(*GRID), ref["analyze"])
            elif op == "check":
                ok = all(r["ok"] for r in m.check(samples=1, digits=20))
            elif op == "generate":
                ok = pathlib.Path(m.generate(str(out))).read_text() == ref["header"]
            elif op == "eval":
                ok = same(m.eval(t=0.3), ref["eval"])
        except Exception as e:  # noqa: BLE001 (any failure is a finding)
            ok = False
            failures.append(f"{op} {path}: {e!r}")
        tally[op] = tally.get(op, 0) + 1
        if not ok:
            failures.append(f"{op} {path}: differs from the single-threaded result")


def main():
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 3.0
    count = int(sys.argv[2]) if len(sys.argv) > 2 else 8
    with tempfile.TemporaryDirectory() as tmp:
        scratch = pathlib.Path(tmp)
        refs = {p: reference(p, scratch) for p in FILES}
        tallies = [{} for _ in range(count)]
        failures = []
        threads = [threading.Thread(target=worker, args=(k, refs, seconds, scratch, tallies[k],
                                                         failures)) for k in range(count)]
        start = time.monotonic()
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        total = {}
        for tally in tallies:
            for op, n in tally.items():
                total[op] = total.get(op, 0) + n
        print(f"{count} threads, {time.monotonic() - start:.1f} s: " +
              ", ".join(f"{op} {n}" for op, n in sorted(total.items())) +
              f"; {len(failures)} failures")
        for f in failures[:10]:
            print("  " + f)
        return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())

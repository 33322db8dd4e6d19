#!/usr/bin/env python3
"""ctest demo_targets: scripts/demo.sh builds only what it runs. Its build targets
(`scripts/demo.sh --targets`) and everything they depend on, read from the build tree's
CMakeFiles/Makefile2 (the Unix Makefiles generator's target graph), hold no target of the test
suite, the Python module, the benchmarks or the examples.

  demo_targets_test.py SOURCE_DIR BUILD_DIR
"""
import os
import re
import subprocess
import sys

# Folders whose targets a demo must not build (they are scripts/test.sh's).
EXCLUDED = ("tests/", "python/", "bench/", "examples/", "fuzz/", "viewer/")


def main():
    source, build = sys.argv[1], sys.argv[2]
    targets = subprocess.run([os.path.join(source, "scripts", "demo.sh"), "--targets"],
                             check=True, stdout=subprocess.PIPE, text=True).stdout.split()
    if "kinegen" not in targets:
        print(f"the demo's targets {targets} lack kinegen, which it runs")
        return 1
    deps = {}
    with open(os.path.join(build, "CMakeFiles", "Makefile2"), encoding="utf-8") as f:
        for line in f:
            m = re.match(r"^(\S*all):\s*(\S.*)?$", line)
            if m:
                deps.setdefault(m.group(1), set()).update((m.group(2) or "").split())
    # A target's node is DIR/CMakeFiles/NAME.dir/all (DIR empty at the top level); `all` is
    # every folder's DIR/all.
    start = []
    for t in targets:
        nodes = [n for n in deps if n == t == "all" or
                 re.search(rf"(^|/)CMakeFiles/{re.escape(t)}\.dir/all$", n)]
        if len(nodes) != 1:
            print(f"target {t}: {len(nodes)} nodes in Makefile2")
            return 1
        start += nodes
    seen, todo = set(), list(start)
    while todo:
        n = todo.pop()
        if n in seen:
            continue
        seen.add(n)
        todo += [d for d in deps.get(n, ()) if d.endswith("all")]
    names = sorted(re.sub(r"CMakeFiles/([^/]+)\.dir/all$", r"\1", n) for n in seen)
    bad = [n for n in names if n.startswith(EXCLUDED) or "test" in n.rsplit("/", 1)[-1]]
    print("the demo builds:", ", ".join(names))
    if bad:
        print("and must not build:", ", ".join(bad))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

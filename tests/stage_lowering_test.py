#!/usr/bin/env python3
"""ctest stage_lowering: the compile stage owns every lowered program. No source of the two
consumers (codegen/src/analysis, codegen/src/emit and their headers) lowers symbolic
expressions itself: a call of `lower(...)`, `lower_model(...)` or another `lower_*(...)`
there (std::lower_bound aside) fails, naming the file and line. Comments and strings
(the emitter's printed text) are blanked first (scripts/check_lengths.py's `blank`).

The calls listed in KNOWN stand, each with its reason: the force functions' geometry, which
the emitter builds together with the text that reads it and the analysis computes in double
instead (no second lowering of the same expressions); and, as debt to repay, the spatial
header's branch and continuation programs. A listed call that is gone fails too,
so the list only shrinks.

  stage_lowering_test.py SOURCE_DIR
"""
import os
import re
import sys

CONSUMERS = ("codegen/src/analysis", "codegen/src/emit", "codegen/include/kinegen/codegen/analysis",
             "codegen/include/kinegen/codegen/emit")
KNOWN = {("codegen/src/emit/emit_forces.cpp", "lower(geometry, symbols_)"),
         # Debt, not design: the spatial header's branch conditions and its drivers' continued
         # rows, lowered where they are printed; they belong in CompiledModel (as
         # stop_programs() are) before the command line's continuation runs them too.
         ("codegen/src/emit/emit_spatial.cpp", "lower(conditions, s)"),
         ("codegen/src/emit/emit_spatial.cpp", "lower(start_and_target, s)"),
         ("codegen/src/emit/emit_spatial.cpp", "lower(row_programs[d], s)")}
CALL = re.compile(r"(?<![\w.])(?:\w+::)*lower(?:_(?!bound\b)\w+)?\s*\(")


def offenders(root):
    sys.path.insert(0, os.path.join(root, "scripts"))
    from check_lengths import blank  # noqa: E402
    found = []
    for folder in CONSUMERS:
        for d, _, names in os.walk(os.path.join(root, folder)):
            for name in sorted(names):
                if not name.endswith((".cpp", ".hpp")):
                    continue
                path = os.path.join(d, name)
                with open(path, encoding="utf-8") as f:
                    text = blank(f.read())
                for n, line in enumerate(text.split("\n"), 1):
                    if CALL.search(line):
                        found.append((os.path.relpath(path, root), n, line.strip()))
    return found


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else "."
    found = offenders(root)
    known = {(f, text) for f, text in KNOWN for g, _, line in found if g == f and text in line}
    new = [(f, n, line) for f, n, line in found
           if not any(g == f and text in line for g, text in KNOWN)]
    for f, n, line in new:
        print(f"{f}:{n}: {line}")
    for f, text in sorted(KNOWN - known):
        print(f"{f}: the listed call `{text}` is gone: remove it from KNOWN")
    if new or known != KNOWN:
        print(f"{len(new)} lowering call(s) outside the compile stage: take the program from "
              "the CompiledModel (compile/compiled_model.hpp) instead")
        return 1
    print(f"no lowering outside the compile stage but the {len(KNOWN)} listed")
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""ctest repo_references: the repository stands alone. No file refers to the contract outside
it (the shared folder beside a checkout, the contract's file name) or cites another document's section numbers
("format 7.1", "section 6.5", "spec 8.3", "(6.5)", "7.3 amendment"); docs/format.md is the
project's reference and is cited by section title. docs/format.md's own numbers are its own.

  repo_references_test.py SOURCE_DIR     prints each offending line as FILE:LINE: TEXT
"""
import os
import re
import subprocess
import sys

HERE = "tests/repo_references_test.py"
REFERENCE = "docs/format.md"
SKIP_DIRS = {".git", "node_modules", "out"}
DATA = (".svg", ".png", ".csv", ".json")  # figures and data: numbers, not citations
# Anywhere, format.md included.
OUTSIDE = re.compile(r"\.\./shared|mechanism" r"-format\.md")
# A section number cited in words: "format 7.1", "section 6", "sections 1-7", "spec 8.3",
# "format.md 8.2", "§ 6.5", "7.3 amendment".
CITED = re.compile(
    r"\b(?:format|sections?|spec|specification|contract)(?:\.md)?[ ,:]+\(?[1-9](?:\.[0-9]+)?\b"
    r"|§\s*[0-9]|\b[1-9]\.[0-9]+ amendment|\bsection [1-9] amendment", re.I)
# A bare "(6.5)" or "(6.5, 7.3)": a section number in parentheses.
BARE = re.compile(r"(?<![\w.])\((?:[1-9]\.[1-9][0-9]?)(?:(?:, | and |-)[1-9]\.[1-9][0-9]?)*\)")


def files(root):
    try:
        out = subprocess.run(["git", "-C", root, "ls-files", "-z"], check=True,
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL).stdout
        return [f for f in out.decode().split("\0") if f]
    except (OSError, subprocess.CalledProcessError):
        found = []
        for d, dirs, names in os.walk(root):
            dirs[:] = [x for x in dirs if x not in SKIP_DIRS and not x.startswith("build")]
            found += [os.path.relpath(os.path.join(d, n), root) for n in names]
        return found


def main():
    root = sys.argv[1]
    bad = 0
    for rel in sorted(files(root)):
        if rel == HERE or rel.endswith(DATA):
            continue
        path = os.path.join(root, rel)
        try:
            with open(path, encoding="utf-8") as f:
                lines = f.read().split("\n")
        except (UnicodeDecodeError, IsADirectoryError, FileNotFoundError):
            continue  # binary files (figures), submodules
        for n, line in enumerate(lines, 1):
            hit = OUTSIDE.search(line) or (rel != REFERENCE and
                                           (CITED.search(line) or BARE.search(line)))
            if hit:
                bad += 1
                print(f"{rel}:{n}: {line.strip()[:160]}")
    if bad:
        print(f"{bad} lines refer outside the repository or to another document's section "
              f"numbers: cite docs/format.md by section title instead")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Runs the code blocks of the README and docs/ (ctest doc_blocks), so that what they show stays
true.

  check_doc_blocks.py --kinegen EXE --source ROOT --work DIR [--python-path P] [--cxx CXX]
                      [--eigen DIR] FILE.md ...

A block is a fenced block; the first word of its info string is its language and the words after
it are flags (GitHub shows only the language):
  console, sh   each `$ command` (a trailing backslash continues it) runs in bash in a scratch
                folder that sees the repository's examples/, tests/, generated/, scripts/ and
                runtime/, with `kinegen` on PATH. The lines after a command, up to the next
                `$`, are its output: unless they hold `...`, they must equal what it prints
                (standard output and error). A command whose output shows an `error:` line must
                exit non-zero, any other must exit 0.
  yaml          a whole mechanism (it has `bodies:`) must load and assemble
                (`kinegen analyze FILE --steps 0`); a part of one needs `from=PATH`, and its
                lines must appear in that file in order.
  cpp           a whole program (it has `int main`) is compiled against the runtime and the
                committed generated headers, and run; otherwise `from=PATH` as for yaml.
  python        runs, with the module on PYTHONPATH.
  cmake         needs `from=PATH`.
Flags: `norun` (shown, not run: setup commands, an interface summary), `from=PATH` (an excerpt),
`nocompare` (run, exit status checked, output not compared). Blocks without a language are text.
Prints one line per block and a summary; exits 1 if any block fails.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys

LINKED = ["examples", "tests", "generated", "scripts", "runtime", "docs", "viewer", "bench"]


def blocks(path):
    """Yields (line, language, flags, text) for each fenced block of a Markdown file."""
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    i = 0
    while i < len(lines):
        m = re.match(r"^(\s*)```(.*)$", lines[i])
        if not m:
            i += 1
            continue
        indent, info = len(m.group(1)), m.group(2).split()
        start, body = i + 1, []
        i += 1
        while i < len(lines) and not re.match(r"^\s*```\s*$", lines[i]):
            body.append(lines[i][indent:] if lines[i][:indent].strip() == "" else lines[i])
            i += 1
        i += 1
        lang = info[0] if info else ""
        flags = {}
        for word in info[1:]:
            key, _, value = word.partition("=")
            flags[key] = value or True
        yield start, lang, flags, "\n".join(body)


def excerpt_ok(text, source_root, rel):
    """True when the block's non-empty lines appear in the file, in order."""
    path = os.path.join(source_root, rel)
    if not os.path.isfile(path):
        return False, f"from={rel}: no such file"
    with open(path, encoding="utf-8") as f:
        have = [" ".join(l.split()) for l in f.read().split("\n")]
    k = 0
    for want in (" ".join(l.split()) for l in text.split("\n")):
        if not want:
            continue
        while k < len(have) and have[k] != want:
            k += 1
        if k == len(have):
            return False, f"line not in {rel} (in order): {want}"
        k += 1
    return True, ""


def console_steps(text):
    """Splits a console block into (command, expected output lines)."""
    steps, lines = [], text.split("\n")
    i = 0
    while i < len(lines):
        if not lines[i].startswith("$ "):
            i += 1
            continue
        cmd = lines[i][2:]
        while cmd.endswith("\\") and i + 1 < len(lines):
            i += 1
            cmd = cmd[:-1] + " " + lines[i].strip()
        i += 1
        out = []
        while i < len(lines) and not lines[i].startswith("$ "):
            out.append(lines[i])
            i += 1
        while out and not out[-1].strip():
            out.pop()
        steps.append((cmd, out))
    return steps


def run(cmd, env, cwd, timeout=600):
    return subprocess.run(["bash", "-c", cmd], cwd=cwd, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, timeout=timeout, text=True)


def check_console(text, flags, env, cwd, update=None):
    new_text = text
    for cmd, want in console_steps(text):
        r = run(cmd, env, cwd)
        got = r.stdout.rstrip("\n").split("\n") if r.stdout.strip() else []
        expect_error = any(l.startswith("error:") for l in want)
        if expect_error != (r.returncode != 0):
            return False, f"`{cmd}` exited {r.returncode}:\n{r.stdout[-2000:]}"
        compare = not flags.get("nocompare") and not any("..." in l for l in want)
        if not compare or [l.rstrip() for l in got] == [l.rstrip() for l in want]:
            continue
        old = "\n".join(want)
        if update is not None and old and old in new_text:
            new_text = new_text.replace(old, "\n".join(got), 1)
        else:
            diff = [f"  want: {w}\n  got:  {g}" for w, g in zip(want + [""] * len(got),
                                                                 got + [""] * len(want)) if
                    w.rstrip() != g.rstrip()]
            return False, f"`{cmd}` printed something else:\n" + "\n".join(diff[:6])
    if update is not None and new_text != text:
        update.append((text, new_text))
    return True, ""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--kinegen", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--python-path", default="")
    ap.add_argument("--cxx", default="g++")
    ap.add_argument("--eigen", default="/usr/include/eigen3")
    ap.add_argument("--update", action="store_true",
                    help="rewrite the shown output of console blocks with what they print")
    ap.add_argument("files", nargs="+")
    a = ap.parse_args()
    src = os.path.abspath(a.source)
    if os.path.isdir(a.work):
        shutil.rmtree(a.work)
    os.makedirs(os.path.join(a.work, "bin"))
    os.symlink(os.path.abspath(a.kinegen), os.path.join(a.work, "bin", "kinegen"))
    env = dict(os.environ)
    env["PATH"] = os.path.join(a.work, "bin") + os.pathsep + env.get("PATH", "")
    if a.python_path:
        env["PYTHONPATH"] = os.path.abspath(a.python_path)
    env["MPLBACKEND"] = "Agg"
    failed = ran = shown = 0
    for md in a.files:
        rel_md = os.path.relpath(md, src)
        for n, (line, lang, flags, text) in enumerate(blocks(md)):
            where = f"{rel_md}:{line}"
            if not lang or lang in ("text", "mermaid"):
                continue
            if flags.get("norun"):
                shown += 1
                continue
            cwd = os.path.join(a.work, f"{rel_md.replace('/', '_')}_{n}")
            os.makedirs(cwd)
            for d in LINKED:
                if os.path.exists(os.path.join(src, d)):
                    os.symlink(os.path.join(src, d), os.path.join(cwd, d))
            os.makedirs(os.path.join(cwd, "out"))
            ok, why = True, ""
            try:
                if flags.get("from"):
                    ok, why = excerpt_ok(text, src, flags["from"])
                elif lang in ("console", "sh"):
                    changes = [] if a.update else None
                    ok, why = check_console(text, flags, env, cwd, changes)
                    if changes:
                        with open(md, encoding="utf-8") as f:
                            page = f.read()
                        with open(md, "w", encoding="utf-8") as f:
                            f.write(page.replace(changes[0][0], changes[0][1], 1))
                        print(f"updated {where}")
                elif lang == "yaml":
                    if not re.search(r"^bodies:", text, re.M):
                        ok, why = False, "a part of a mechanism needs from=PATH"
                    else:
                        with open(os.path.join(cwd, "block.yaml"), "w") as f:
                            f.write(text + "\n")
                        r = run("kinegen analyze block.yaml --t0 0 --t1 0 --steps 0 -o -", env,
                                cwd)
                        ok, why = r.returncode == 0, r.stdout[-2000:]
                elif lang == "cpp":
                    if "int main" not in text:
                        ok, why = False, "a part of a program needs from=PATH"
                    else:
                        with open(os.path.join(cwd, "block.cpp"), "w") as f:
                            f.write(text + "\n")
                        r = run(f"{a.cxx} -std=c++17 -O1 -I{src}/runtime/include "
                                f"-I{src}/generated -I{a.eigen} block.cpp -o block && ./block",
                                env, cwd)
                        ok, why = r.returncode == 0, r.stdout[-2000:]
                elif lang == "python":
                    with open(os.path.join(cwd, "block.py"), "w") as f:
                        f.write(text + "\n")
                    r = run(f"{sys.executable} block.py", env, cwd)
                    ok, why = r.returncode == 0, r.stdout[-2000:]
                else:
                    ok, why = False, f"language '{lang}' needs from=PATH or norun"
            except subprocess.TimeoutExpired:
                ok, why = False, "timed out"
            ran += 1
            if not ok:
                failed += 1
                print(f"FAIL {where} ({lang}): {why}")
            else:
                print(f"ok   {where} ({lang})")
    print(f"{ran - failed} of {ran} blocks hold; {shown} marked norun (shown, not run)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

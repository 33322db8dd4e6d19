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
                (`kinegen analyze FILE --steps 0`; with `free:`, a `kinegen simulate` of one
                short step, which also checks the free items' counts and masses); a part of one needs `from=PATH`, and its
                lines must appear in that file in order, or `into=PATH`: its top-level keys
                are added to the mechanism PATH (a list's items appended, a mapping's keys
                set, any other value replaced) and the result must load (`kinegen eval`).
  cpp           a whole program (it has `int main`) is compiled against the runtime and the
                committed generated headers, and run; otherwise `from=PATH` as for yaml.
  python        runs, with the module on PYTHONPATH.
  cmake         needs `from=PATH`.
Flags: `norun` (shown, not run: setup commands, an interface summary), `from=PATH` (an excerpt),
`into=PATH` (a part of a mechanism, added to PATH),
`nocompare` (run, exit status checked, output not compared). Blocks without a language are text.
With `--reference FILE.md` (docs/format.md) the check also asks kinegen which keys it reads
(the message an unknown key gets lists them): every top-level key, every type of joint, driver,
free item and load, and every key of each must appear in a tested yaml block of that page (a
key that every type of a list takes, such as `name`, once per list).
Prints one line per block and a summary; exits 1 if any block fails.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys

import yaml

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


def merged_mechanism(text, source_root, rel):
    """The mechanism at rel with the block's top-level keys added, as YAML text, or an error."""
    path = os.path.join(source_root, rel)
    if not os.path.isfile(path):
        return None, f"into={rel}: no such file"
    with open(path, encoding="utf-8") as f:
        base = yaml.safe_load(f)
    part = yaml.safe_load(text)
    if not isinstance(part, dict):
        return None, "a part of a mechanism is a mapping of top-level keys"
    for key, value in part.items():
        if isinstance(value, list) and isinstance(base.get(key), list):
            base[key] = base[key] + value
        elif isinstance(value, dict) and isinstance(base.get(key), dict):
            base[key] = {**base[key], **value}
        else:
            base[key] = value
    return yaml.safe_dump(base, sort_keys=False), ""


GENERIC = {"name", "period", "table", "value0", "v0"}


def expected_keys(doc, env, cwd):
    """The keys kinegen lists for an unknown key (or type) in doc, in its message's order."""
    with open(os.path.join(cwd, "probe.yaml"), "w") as f:
        yaml.safe_dump(doc, f, sort_keys=False)
    r = run("kinegen eval probe.yaml", env, cwd)
    m = re.search(r"\(expected(?: one of)?: ([^)]*)\)", r.stdout)
    if not m:
        raise RuntimeError(f"no list of keys in: {r.stdout.strip()}")
    return m.group(1).split(", ")


def keys_kinegen_reads(env, cwd):
    """{(list, type or None): [keys]} and {list: [types]}, as kinegen's loader names them."""
    body = {"name": "b", "q0": [0, 0, 0]}
    base = {"name": "probe", "bodies": [body]}
    probe = "zz_probe"
    keys = {("top", None): expected_keys({**base, probe: 1}, env, cwd),
            ("bodies", None): expected_keys({**base, "bodies": [{**body, probe: 1}]}, env, cwd),
            ("coordinates", None): expected_keys(
                {**base, "coordinates": [{"name": "c", "q0": 0, probe: 1}]}, env, cwd),
            ("points", None): expected_keys(
                {**base, "points": [{"name": "p", "body": "b", probe: 1}]}, env, cwd),
            ("pieces", None): expected_keys(
                {**base, "drivers": [{"type": "absolute_angle", "body": "b",
                                      "f": [{"until": 1, "f": "0", probe: 1}, {"f": "0"}]}]},
                env, cwd)}
    types = {}
    for lst in ("joints", "drivers", "free", "forces"):
        types[lst] = expected_keys({**base, lst: [{"type": probe}]}, env, cwd)
        for t in types[lst]:
            keys[(lst, t)] = [k for k in expected_keys({**base, lst: [{"type": t, probe: 1}]},
                                                       env, cwd) if k != "type"]
    return keys, types


def keys_shown(parsed):
    """(list, type, key) triples in a parsed block; list None where the block does not say."""
    seen = set()
    lists = ("joints", "drivers", "free", "forces", "bodies", "coordinates", "points")

    def items(lst, value):
        for item in value if isinstance(value, list) else []:
            if not isinstance(item, dict):
                continue
            for k, v in item.items():
                seen.add((lst, item.get("type"), k))
                if k == "f" and isinstance(v, list):
                    for piece in v:
                        if isinstance(piece, dict):
                            seen.update(("pieces", None, pk) for pk in piece)

    if isinstance(parsed, dict):
        for k, v in parsed.items():
            seen.add(("top", None, k))
            if k in lists:
                items(k, v)
    elif isinstance(parsed, list):
        items(None, parsed)
    return seen


def coverage(shown, keys, types):
    """What kinegen reads that no tested block of the reference shows."""
    missing = []
    def has(lst, t, k):
        return any(s[2] == k and s[0] in (lst, None) and (t is None or s[1] == t) for s in shown)
    for (lst, t), ks in keys.items():
        if t is not None:
            continue
        missing += [f"{lst}: key '{k}'" for k in ks if not has(lst, None, k)]
    for lst, ts in types.items():
        # Keys that any type of the list takes (or most: a law's period and table) once per list.
        every = set.intersection(*(set(keys[(lst, t)]) for t in ts)) | GENERIC
        for t in ts:
            if not has(lst, t, "type") and not any(s[1] == t and s[0] in (lst, None) for s in shown):
                missing.append(f"{lst}: type '{t}'")
                continue
            for k in keys[(lst, t)]:
                ok = has(lst, None, k) if k in every else has(lst, t, k)
                if not ok:
                    missing.append(f"{lst}: {t} key '{k}'")
    return sorted(set(missing))


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
    ap.add_argument("--reference", help="the page that must show every key kinegen reads")
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
    reference_shown = set()
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
                elif lang == "yaml" and flags.get("into"):
                    merged, why = merged_mechanism(text, src, flags["into"])
                    ok = merged is not None
                    if ok:
                        with open(os.path.join(cwd, "block.yaml"), "w") as f:
                            f.write(merged)
                        r = run("kinegen eval block.yaml", env, cwd)
                        ok, why = r.returncode == 0, r.stdout[-2000:]
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
                        if re.search(r"^free:", text, re.M):
                            cmd = "kinegen simulate block.yaml --t1 1e-3 --steps 1 -q -o -"
                        else:
                            cmd = "kinegen analyze block.yaml --t0 0 --t1 0 --steps 0 -o -"
                        r = run(cmd, env, cwd)
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
            if ok and lang == "yaml" and a.reference and os.path.samefile(md, a.reference):
                try:
                    reference_shown |= keys_shown(yaml.safe_load(text))
                except yaml.YAMLError:
                    pass
            ran += 1
            if not ok:
                failed += 1
                print(f"FAIL {where} ({lang}): {why}")
            else:
                print(f"ok   {where} ({lang})")
    print(f"{ran - failed} of {ran} blocks hold; {shown} marked norun (shown, not run)")
    if a.reference:
        probe_dir = os.path.join(a.work, "keys")
        os.makedirs(probe_dir)
        keys, types = keys_kinegen_reads(env, probe_dir)
        missing = coverage(reference_shown, keys, types)
        n = sum(len(v) for v in keys.values()) + sum(len(v) for v in types.values())
        for m in missing:
            print(f"FAIL {os.path.relpath(a.reference, src)}: no tested yaml block shows {m}")
        print(f"{os.path.relpath(a.reference, src)}: {len(missing)} of the {n} keys and types "
              f"kinegen reads missing from its tested blocks")
        failed += len(missing)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

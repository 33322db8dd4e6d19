#!/usr/bin/env python3
"""The size rule of the code (HELPERS.md, "How we write code"): no file under codegen/src or
runtime/include over 600 lines, no function over 80 lines.

A function is a brace block opened at namespace or class scope whose head ends in a parameter
list (and qualifiers); its length runs from the first line of its head (template line
included) to its closing brace. Comments, strings (raw strings too) and preprocessor lines
are blanked first, so braces in them do not count.

A ceiling in scripts/length_debt.txt (`FILE LINES` or `FILE FUNCTION LINES`) lets a known
offender stand at no more than its size there, until the pipeline issue's move splits it: a
new offender, one grown past its ceiling, or a ceiling no longer needed fails the run, so the
list only shrinks.

  scripts/check_lengths.py [--top N] [ROOT]   exit 1 and a line per offender if the rule fails
"""
import argparse
import os
import re
import sys

MAX_FILE_LINES = 600
MAX_FUNCTION_LINES = 80
FOLDERS = ("codegen/src", "runtime/include")


def blank(text):
    """The text with comments, string and character literals and preprocessor lines replaced
    by spaces (newlines kept, so offsets and line numbers stay)."""
    out = list(text)
    i, n = 0, len(text)

    def wipe(a, b):
        for k in range(a, b):
            if out[k] != "\n":
                out[k] = " "

    at_line_start = True
    while i < n:
        c = text[i]
        if at_line_start and c == "#":
            j = i
            while j < n and (text[j] != "\n" or text[j - 1] == "\\"):
                j += 1
            wipe(i, j)
            i = j
            continue
        if c == "\n":
            at_line_start = True
            i += 1
            continue
        if not c.isspace():
            at_line_start = False
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            wipe(i, j)
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            wipe(i, j)
            i = j
        elif c == "R" and text.startswith('"', i + 1) and not (i and (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            end = text.find(")" + m.group(1) + '"', i + m.end())
            j = n if end < 0 else end + len(m.group(1)) + 2
            wipe(i, j)
            i = j
        elif c == '"' or (c == "'" and not (i and text[i - 1].isalnum())):
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            wipe(i, j + 1)
            i = j + 1
        else:
            i += 1
    return "".join(out)


FUNCTION_HEAD = re.compile(
    r"\)\s*(const|noexcept(\([^)]*\))?|override|final|mutable|&|&&|->\s*[\w:<>,\s*&]+|\s)*$")
ACCESS_LABEL = re.compile(r"\s*(public|private|protected)\s*:(?!:)")
SCOPE_HEAD = re.compile(r"\b(namespace|class|struct|union)\b|^\s*extern\s*$")


def functions(text):
    """(name, first line, last line) of each function in the text."""
    code = blank(text)
    line_of = [0] * (len(code) + 1)
    line = 1
    for k, ch in enumerate(code):
        line_of[k] = line
        if ch == "\n":
            line += 1
    stack = []  # one entry per open brace: "scope", "function" or "other"
    head_start = 0
    found = []
    opened = []
    for k, ch in enumerate(code):
        if ch in ";{}":
            inside_function = any(s != "scope" for s in stack)
            if ch == "{":
                head = code[head_start:k]
                if inside_function:
                    kind = "other"
                elif FUNCTION_HEAD.search(head) and not re.search(r"=\s*[\[{(]", head.split("(")[0]):
                    kind = "function"
                elif SCOPE_HEAD.search(head) and "(" not in head and "=" not in head:
                    kind = "scope"
                elif re.search(r"\benum\b", head):
                    kind = "other"
                elif FUNCTION_HEAD.search(head):
                    kind = "function"  # a lambda held by a variable
                else:
                    kind = "other"
                stack.append(kind)
                label = ACCESS_LABEL.match(head)
                body = head[label.end():] if label else head
                start = k - len(body) + len(body) - len(body.lstrip())
                opened.append((kind, start, head))
            elif ch == "}" and stack:
                kind = stack.pop()
                _, start, head = opened.pop()
                if kind == "function":
                    name = re.findall(r"([~\w:]+)\s*\(", head)
                    found.append((name[0] if name else "?", line_of[start], line_of[k]))
            head_start = k + 1
    return found


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", nargs="?", default=os.path.join(os.path.dirname(__file__), ".."))
    parser.add_argument("--top", type=int, default=0, help="print the N longest functions")
    args = parser.parse_args()
    failures, all_functions = [], []
    debt, used = {}, set()
    debt_path = os.path.join(args.root, "scripts", "length_debt.txt")
    if os.path.exists(debt_path):
        with open(debt_path, encoding="utf-8") as f:
            for row in f:
                words = row.split("#")[0].split()
                if words:
                    debt[tuple(words[:-1])] = int(words[-1])

    def over(key, length, limit, text):
        if length <= limit:
            return
        if key in debt:
            used.add(key)
            if length <= debt[key]:
                return
        ceiling = f" (its ceiling in length_debt.txt is {debt[key]})" if key in debt else ""
        failures.append(text + ceiling)

    for folder in FOLDERS:
        for base, _, names in os.walk(os.path.join(args.root, folder)):
            for name in sorted(names):
                if not name.endswith((".cpp", ".hpp", ".h", ".cc")):
                    continue
                path = os.path.join(base, name)
                rel = os.path.relpath(path, args.root)
                with open(path, encoding="utf-8") as f:
                    text = f.read()
                lines = text.count("\n")
                over((rel,), lines, MAX_FILE_LINES,
                     f"{rel}: {lines} lines (at most {MAX_FILE_LINES})")
                for fn, first, last in functions(text):
                    length = last - first + 1
                    all_functions.append((length, rel, first, fn))
                    over((rel, fn), length, MAX_FUNCTION_LINES,
                         f"{rel}:{first}: {fn} is {length} lines (at most {MAX_FUNCTION_LINES})")
    for length, rel, first, fn in sorted(all_functions, reverse=True)[: args.top]:
        print(f"{length:5d}  {rel}:{first}  {fn}")
    for key in sorted(set(debt) - used):
        failures.append(f"length_debt.txt: {' '.join(key)} is within the rule now: remove it")
    for line in failures:
        print(line, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

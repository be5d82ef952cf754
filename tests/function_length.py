#!/usr/bin/env python3
"""Short functions: the ctest test `function_length`.

    function_length.py REPO            the check (exit 1 naming each function over the limit)
    function_length.py REPO --list N   the N longest functions, longest first

Every function defined in a C / C++ file under lib/, apps/ and benchmarks/ has at most LIMIT
lines, counted from the first line of its definition (return type and name) to its closing brace.
The files that other work edits now are in KNOWN: their long functions are reported and do not
fail, and the round that splits them empties the list (a KNOWN file with no function over the
limit is reported, so that it is deleted). Comments, strings and preprocessor lines are skipped
when the braces are matched.
"""
import fnmatch
import os
import re
import sys

LIMIT = 120
ROOTS = ["lib", "apps", "benchmarks"]
# Files whose long functions are split by the round that edits them next (empty: every file keeps
# the limit).
KNOWN = []


def strip(text):
    """The text with comments, string / character literals and preprocessor lines blanked
    (newlines kept, so that line numbers stay)."""
    out, i, n = [], 0, len(text)
    line_start = True
    while i < n:
        c = text[i]
        if line_start and c in " \t":
            out.append(c)
            i += 1
            continue
        if line_start and c == "#":  # a directive, with its continuation lines
            while i < n and text[i] != "\n":
                if text[i] == "\\" and i + 1 < n and text[i + 1] == "\n":
                    out.append("\n")
                    i += 2
                    continue
                i += 1
            continue
        line_start = False
        if text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(c + " " * (min(j, n - 1) - i - 1) + c)
            i = j + 1
        else:
            out.append(c)
            if c == "\n":
                line_start = True
            i += 1
    return "".join(out)


NAME = re.compile(r"([A-Za-z_][A-Za-z_0-9]*)\s*\($")  # the name before a definition's first (


def functions(path):
    """(name, first line, lines) of every function defined in the file."""
    text = strip(open(path, encoding="utf-8", errors="replace").read())
    found, depth, i, n = [], 0, 0, len(text)
    decl_start = 0  # where the current top-level declaration starts
    while i < n:
        c = text[i]
        if c == "{":
            if depth == 0:
                head = text[decl_start:i].strip()
                m = NAME.search(head[: head.find("(") + 1]) if head.endswith(")") else None
                if m:
                    start = text.count("\n", 0, text.index(head, decl_start)) + 1
                    found.append([m.group(1), start, None])
            depth += 1
        elif c == "}":
            depth -= 1
            if depth == 0:
                if found and found[-1][2] is None:
                    found[-1][2] = text.count("\n", 0, i) + 1 - found[-1][1] + 1
                decl_start = i + 1
        elif c == ";" and depth == 0:
            decl_start = i + 1
        i += 1
    return [(name, start, lines) for name, start, lines in found if lines is not None]


def all_functions(repo):
    for root in ROOTS:
        for dirpath, dirnames, files in os.walk(os.path.join(repo, root)):
            dirnames.sort()
            for f in sorted(files):
                if f.endswith((".c", ".cpp")):
                    path = os.path.join(dirpath, f)
                    rel = os.path.relpath(path, repo)
                    for name, start, lines in functions(path):
                        yield rel, name, start, lines


def main():
    if len(sys.argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    repo = sys.argv[1]
    rows = list(all_functions(repo))
    if len(sys.argv) == 4 and sys.argv[2] == "--list":
        for rel, name, start, lines in sorted(rows, key=lambda r: -r[3])[: int(sys.argv[3])]:
            print("%5d  %s:%d %s" % (lines, rel, start, name))
        return 0
    if len(rows) < 1000:
        print("function_length: only %d functions under %s: wrong folder?" % (len(rows), repo), file=sys.stderr)
        return 1
    bad, known_files = 0, set()
    for rel, name, start, lines in rows:
        if lines <= LIMIT:
            continue
        if any(fnmatch.fnmatchcase(rel, p) for p in KNOWN):
            known_files.add(rel)
            print("function_length: known: %s:%d %s: %d lines" % (rel, start, name, lines))
        else:
            bad += 1
            print("function_length: FAIL: %s:%d %s: %d lines (at most %d: split it into named steps)"
                  % (rel, start, name, lines, LIMIT), file=sys.stderr)
    for p in KNOWN:
        if not any(fnmatch.fnmatchcase(f, p) for f in known_files):
            print("function_length: no function of %s is over %d lines now: delete it from KNOWN once the work on "
                  "it is in" % (p, LIMIT))
    if bad:
        print("function_length: %d function(s) over %d lines" % (bad, LIMIT), file=sys.stderr)
        return 1
    print("function_length: %d functions, none over %d lines outside the known files" % (len(rows), LIMIT))
    return 0


if __name__ == "__main__":
    sys.exit(main())

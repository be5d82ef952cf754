#!/usr/bin/env python3
"""The usage lines of the docs, written from the tool (`make docs-usage`).

Each command's usage in the docs is the `smplpix CMD ...` statement (the line and the indented lines
that continue it) in the first ```sh block of the section whose heading names `smplpix CMD`, on the
page that docs/commands.md's table "Where each command is described" gives it. This script replaces
that statement with what `smplpix CMD --usage` prints (the synopsis made from the command's option
table, apps/cli_opts.h), or adds it at the end of the block when the block has none; everything else
in the block is left alone. tests/cli_options_docs.py imports it to check that nothing drifted.

usage: docs_usage.py TOOL SOURCE_DIR [--check]
"""
import os
import re
import subprocess
import sys


def commands(tool):
    """The tool's commands, from its own list (`smplpix --help`)."""
    out = subprocess.run([tool, "--help"], capture_output=True, text=True, check=True).stdout
    body = out.split("commands:\n", 1)[1].split("\n\n", 1)[0]
    return [line.split()[0] for line in body.splitlines() if line.strip()]


def usage(tool, cmd):
    """`smplpix CMD --usage`: the synopsis lines, as the docs show them."""
    out = subprocess.run([tool, cmd, "--usage"], capture_output=True, text=True, check=True).stdout
    return out.rstrip("\n").split("\n")


def pages(src):
    """{command: the docs/ page describing it}, from docs/commands.md's table "Where each command is
    described" ("this page": commands.md)."""
    text = open(os.path.join(src, "docs", "commands.md"), encoding="utf-8").read()
    m = re.search(r"^## Where each command is described\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    out = {}
    for row in (m.group(1).splitlines() if m else []):
        cells = [x.strip() for x in row.strip().strip("|").split("|")]
        link = re.search(r"\]\(([^)#]+)", cells[-1])
        page = "commands.md" if cells[-1] == "this page" else link.group(1) if link else None
        for cmd in re.findall(r"`([a-z]+)`", cells[0]) if len(cells) == 2 and page else []:
            out[cmd] = page
    return out


def usage_block(lines, cmd):
    """(first, end): the lines [first, end) inside the first ```sh block of the section whose heading
    names `smplpix CMD`; None when there is no such section or block."""
    heads = [(i, len(m.group(1))) for i, m in ((i, re.match(r"(#+) ", l)) for i, l in enumerate(lines)) if m]
    start = next(((i, n) for i, n in heads if "`smplpix %s`" % cmd in lines[i]), None)
    if start is None:
        return None
    end = next((i for i, n in heads if i > start[0] and n <= start[1]), len(lines))
    first = next((i + 1 for i in range(start[0] + 1, end) if lines[i] == "```sh"), None)
    close = next((i for i in range(first, end) if lines[i].startswith("```")), None) if first else None
    return (first, close) if close else None


def statement(lines, first, end, cmd):
    """(i, j): the lines [i, j) of the `smplpix CMD` statement in lines[first:end], or None."""
    for i in range(first, end):
        if re.match(r"smplpix %s\b" % cmd, lines[i]):
            j = i + 1
            while j < end and lines[j][:1] in (" ", "\t") and lines[j].strip():
                j += 1
            return i, j
    return None


def drift(tool, src, write=False):
    """The problems of the docs' usage blocks (after rewriting them when write)."""
    bad, where = [], pages(src)
    texts, changed = {}, set()
    for cmd in commands(tool):
        page = where.get(cmd)
        if not page:
            bad.append(f"docs/commands.md: smplpix {cmd} is not in the table \"Where each command is described\"")
            continue
        path = os.path.join(src, "docs", page)
        lines = texts.setdefault(path, open(path, encoding="utf-8").read().split("\n"))
        block = usage_block(lines, cmd)
        if not block:
            bad.append(f"docs/{page}: no section whose heading names `smplpix {cmd}` with a ```sh block")
            continue
        want, st = usage(tool, cmd), statement(lines, block[0], block[1], cmd)
        if st and lines[st[0]:st[1]] == want:
            continue
        if write:
            at = st or (block[1], block[1])
            lines[at[0]:at[1]] = want
            changed.add(path)
        else:
            bad.append(f"docs/{page}: the usage of smplpix {cmd} is not what `smplpix {cmd} --usage` prints: "
                       "run make docs-usage")
    for path in changed:
        with open(path, "w", encoding="utf-8") as f:
            f.write("\n".join(texts[path]))
        print(f"wrote the usage lines of {os.path.relpath(path, src)}")
    return bad


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    tool, src, check = sys.argv[1], sys.argv[2], "--check" in sys.argv[3:]
    bad = drift(tool, src, write=not check)
    for b in bad:
        print(b)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

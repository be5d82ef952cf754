#!/usr/bin/env python3
"""Each command's option table (apps/cli_opts.h) is the one source of its options: every option of
the table is in `smplpix CMD --help`, and in CMD's usage in the docs: the `smplpix CMD` lines of the
first ```sh block of the section whose heading names `smplpix CMD`, on the page that docs/commands.md's
table "Where each command is described" gives it (a command missing from that table, or without
such a section, fails); every option the docs' command lines give CMD (```sh blocks of docs/*.md
and README.md) is in the table. The table comes from the test build's tool (smplpix-test-hooks),
which prints it after the help when SPX_TEST_LIST_OPTIONS=1.

usage: cli_options_docs.py TOOL SOURCE_DIR
"""
import glob
import os
import re
import subprocess
import sys

OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")


def commands(tool):
    out = subprocess.run([tool, "--help"], capture_output=True, text=True, check=True).stdout
    body = out.split("commands:\n", 1)[1].split("\n\n", 1)[0]
    return [line.split()[0] for line in body.splitlines() if line.strip()]


def table_and_help(tool, cmd):
    env = dict(os.environ, SPX_TEST_LIST_OPTIONS="1")
    out = subprocess.run([tool, cmd, "--help"], capture_output=True, text=True, env=env, check=True).stdout
    help_text, sep, table = out.rpartition("table options:")
    if not sep:
        sys.exit(f"smplpix {cmd} --help printed no option table (is {tool} the test build's tool?)")
    return table.split(), help_text


def doc_lines(src):
    """(file, command, options) for every `smplpix CMD ...` line of a ```sh block, with the indented
    lines that continue it; comments (` # ...`) left out."""
    files = sorted(glob.glob(os.path.join(src, "docs", "*.md"))) + [os.path.join(src, "README.md")]
    for path in files:
        in_sh, cur = False, None
        for line in open(path, encoding="utf-8"):
            if line.startswith("```"):
                in_sh = line.strip() == "```sh" and not in_sh
                if cur:
                    yield cur
                cur = None
                continue
            if not in_sh:
                continue
            text = line.split(" #", 1)[0].rstrip()
            m = re.match(r"smplpix ([a-z]+)\b", text)
            if m:
                if cur:
                    yield cur
                cur = (os.path.relpath(path, src), m.group(1), OPTION.findall(text))
            elif cur and line[:1] in " \t" and text.strip():
                cur[2].extend(OPTION.findall(text))
            else:
                if cur:
                    yield cur
                cur = None


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


def section_usage(src, page, cmd):
    """The options of the `smplpix CMD` lines (with their continuations) of the first ```sh block of
    the section of docs/PAGE whose heading names `smplpix CMD` (None: no such section)."""
    lines = open(os.path.join(src, "docs", page), encoding="utf-8").read().split("\n")
    heads = [(i, len(m.group(1))) for i, m in ((i, re.match(r"(#+) ", l)) for i, l in enumerate(lines)) if m]
    start = next(((i, n) for i, n in heads if "`smplpix %s`" % cmd in lines[i]), None)
    if start is None:
        return None
    end = next((i for i, n in heads if i > start[0] and n <= start[1]), len(lines))
    block = re.search(r"```sh\n(.*?)```", "\n".join(lines[start[0] + 1:end]), re.S)
    opts, mine = set(), False
    for line in (block.group(1).splitlines() if block else []):
        text = line.split(" #", 1)[0].rstrip()
        m = re.match(r"smplpix ([a-z]+)\b", text)
        if m:
            mine = m.group(1) == cmd
        elif not (line[:1] in " \t" and text.strip()):
            mine = False
        if mine:
            opts |= set(OPTION.findall(text))
    return opts


def main():
    tool, src = sys.argv[1], sys.argv[2]
    bad = []
    tables, where = {}, pages(src)
    for cmd in commands(tool):
        table, help_text = table_and_help(tool, cmd)
        tables[cmd] = set(table)
        in_help = set(OPTION.findall(help_text))
        bad += [f"smplpix {cmd} --help does not name its option {o}" for o in table if o not in in_help]
        page = where.get(cmd)
        usage = section_usage(src, page, cmd) if page else None
        if not page:
            bad.append(f"docs/commands.md: smplpix {cmd} is not in the table \"Where each command is described\"")
        elif usage is None:
            bad.append(f"docs/{page}: no section whose heading names `smplpix {cmd}`")
        else:
            bad += [f"docs/{page}, smplpix {cmd}: its usage lacks the option {o}" for o in table if o not in usage]
    checked = 0
    for path, cmd, opts in doc_lines(src):
        if cmd not in tables:
            bad.append(f"{path}: smplpix {cmd}: no such command")
            continue
        checked += 1
        bad += [f"{path}: smplpix {cmd} {o}: not an option of the command" for o in opts if o not in tables[cmd]]
    for b in bad:
        print(b)
    print(f"{len(tables)} commands, {checked} command lines in the docs: {len(bad)} problems")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Each command's option table (apps/cli_opts.h) is the one source of its options: every option of
the table is in `smplpix CMD --help`, and in the usage block of CMD's section of docs/commands.md
when it has one; every option the docs' command lines give CMD (```sh blocks of docs/*.md and
README.md) is in the table. The table comes from the test build's tool (smplpix-test-hooks), which
prints it after the help when SPX_TEST_LIST_OPTIONS=1.

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


def section_usage(src, cmd):
    """The options of the first ```sh block of docs/commands.md's section `smplpix CMD` (None: no section)."""
    text = open(os.path.join(src, "docs", "commands.md"), encoding="utf-8").read()
    m = re.search(r"^## `smplpix %s`\n(.*?)(?=^## |\Z)" % re.escape(cmd), text, re.S | re.M)
    if not m:
        return None
    block = re.search(r"```sh\n(.*?)```", m.group(1), re.S)
    return set(OPTION.findall(block.group(1))) if block else set()


def main():
    tool, src = sys.argv[1], sys.argv[2]
    bad = []
    tables = {}
    for cmd in commands(tool):
        table, help_text = table_and_help(tool, cmd)
        tables[cmd] = set(table)
        in_help = set(OPTION.findall(help_text))
        bad += [f"smplpix {cmd} --help does not name its option {o}" for o in table if o not in in_help]
        usage = section_usage(src, cmd)
        if usage is not None:
            bad += [f"docs/commands.md, smplpix {cmd}: its usage lacks the option {o}" for o in table if o not in usage]
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

#!/usr/bin/env python3
"""Each command's option table (apps/cli_opts.h) is the one source of its options, its --help and
its usage in the docs: the `smplpix CMD` statement of the first ```sh block of the section whose
heading names `smplpix CMD`, on the page docs/commands.md's table "Where each command is described"
gives it, is exactly what `smplpix CMD --usage` prints (scripts/docs_usage.py, `make docs-usage`,
writes it; a command missing from that table, or without such a section, fails); every option of
the table (every option of that synopsis) is in `smplpix CMD --help`; and every option the docs'
command lines give CMD (```sh blocks of docs/*.md and README.md) is an option of the table.

usage: cli_options_docs.py TOOL SOURCE_DIR
"""
import glob
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
import docs_usage  # noqa: E402

OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")


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


def main():
    tool, src = sys.argv[1], sys.argv[2]
    bad = docs_usage.drift(tool, src)
    tables = {}
    for cmd in docs_usage.commands(tool):
        table = OPTION.findall(" ".join(docs_usage.usage(tool, cmd)))
        tables[cmd] = set(table)
        help_text = subprocess.run([tool, cmd, "--help"], capture_output=True, text=True, check=True).stdout
        in_help = set(OPTION.findall(help_text))
        bad += [f"smplpix {cmd} --help does not name its option {o}" for o in table if o not in in_help]
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

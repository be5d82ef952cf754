#!/usr/bin/env python3
"""The documentation stays a map: the ctest test `docs_map`.

    docs_map.py REPO

- docs/ARCHITECTURE.md has at most MAX_LINES lines and no bullet longer than MAX_BULLET lines;
- every relative link of README.md and docs/*.md names a file or folder of the repository, and
  every in-page anchor (`#name` alone or `page.md#name`) names a heading of its page;
- no comment or page outside benchmarks/RESULTS.md tells history by issue or session number.
Exit 1 naming each finding.
"""
import os
import re
import sys

MAX_LINES = 300
MAX_BULLET = 8
HISTORY = re.compile(r"\b(issue|session) #?[0-9]+\b", re.I)
SCAN_DIRS = ["lib", "apps", "kernels", "tests", "docs", "benchmarks", "scripts", "python", "fuzz", "tools"]
SCAN_EXT = (".c", ".h", ".cpp", ".cl", ".md", ".py", ".sh", ".cmake")


def anchor(heading):
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to '-'."""
    h = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return h.replace(" ", "-")


def anchors(path):
    with open(path, encoding="utf-8") as f:
        return {anchor(m.group(1)) for m in re.finditer(r"^#+\s+(.*)$", f.read(), re.M)}


def check_map(repo, fail):
    path = os.path.join(repo, "docs", "ARCHITECTURE.md")
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    if len(lines) > MAX_LINES:
        fail(f"docs/ARCHITECTURE.md: {len(lines)} lines (at most {MAX_LINES}: details go to the header comments)")
    start = None
    for i, line in enumerate(lines + [""]):
        if re.match(r"^\s*([-*]|\d+\.)\s", line) or not line.strip() or line.startswith("#"):
            if start is not None and i - start > MAX_BULLET:
                fail(f"docs/ARCHITECTURE.md:{start + 1}: a bullet of {i - start} lines (at most {MAX_BULLET})")
            start = i if re.match(r"^\s*([-*]|\d+\.)\s", line) else None


def check_links(repo, fail):
    pages = [os.path.join(repo, "README.md")]
    docs = os.path.join(repo, "docs")
    pages += [os.path.join(docs, n) for n in sorted(os.listdir(docs)) if n.endswith(".md")]
    for page in pages:
        with open(page, encoding="utf-8") as f:
            text = f.read()
        text = re.sub(r"```.*?```", "", text, flags=re.S)
        rel = os.path.relpath(page, repo)
        for m in re.finditer(r"\]\(([^)\s]+)\)", text):
            target = m.group(1)
            if re.match(r"^[a-z]+:", target):
                continue
            file, _, frag = target.partition("#")
            dest = os.path.normpath(os.path.join(os.path.dirname(page), file)) if file else page
            if not os.path.exists(dest):
                fail(f"{rel}: the link '{target}' names no file of the repository")
            elif frag and dest.endswith(".md") and frag not in anchors(dest):
                fail(f"{rel}: the link '{target}' names no heading of {os.path.relpath(dest, repo)}")


def check_history(repo, fail):
    for top in SCAN_DIRS:
        for dirpath, dirnames, files in os.walk(os.path.join(repo, top)):
            dirnames[:] = [d for d in dirnames if d not in ("corpus", "data", "__pycache__")]
            for name in files:
                path = os.path.join(dirpath, name)
                rel = os.path.relpath(path, repo)
                if not name.endswith(SCAN_EXT) or rel == os.path.join("benchmarks", "RESULTS.md"):
                    continue
                with open(path, encoding="utf-8", errors="replace") as f:
                    for n, line in enumerate(f, 1):
                        if HISTORY.search(line):
                            fail(f"{rel}:{n}: history in the tree ('{HISTORY.search(line).group(0)}'): "
                                 "say the rule, keep the history in benchmarks/RESULTS.md")


def main():
    repo = sys.argv[1] if len(sys.argv) > 1 else "."
    found = []
    for check in (check_map, check_links, check_history):
        check(repo, found.append)
    for f in found:
        print("docs_map: " + f)
    print(f"docs_map: {len(found)} finding(s)")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())

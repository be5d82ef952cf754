#!/usr/bin/env python3
"""No file circles: the ctest test `file_circles`.

    file_circles.py --nm NM --src REPO OBJECT...

Builds the file-level call graph of the given object files (the library's and the tool's): file A
calls file B when A's object leaves undefined an external symbol (a function or a variable) that
B's object defines (`nm -P`). Any loop of files (a strongly connected component of two or more
files) fails the test, named with one cycle through it and the symbols that close it. Objects whose
source file is gone (a stale build directory) are skipped; exit 77 (skipped) without nm output.
"""
import argparse
import collections
import os
import subprocess
import sys


def source_of(obj):
    """lib/cl/check.c for .../CMakeFiles/smplpix.dir/lib/cl/check.c.o"""
    rel = obj.split(".dir/", 1)[1] if ".dir/" in obj else os.path.basename(obj)
    return rel[:-2] if rel.endswith(".o") else rel


def symbols(nm, objects):
    """{object: (defined, undefined)} from one `nm -P -A` over all of them."""
    out = subprocess.run([nm, "-P", "-A"] + objects, capture_output=True, text=True, check=True).stdout
    table = {obj: (set(), set()) for obj in objects}
    for line in out.splitlines():
        head, _, rest = line.rpartition(": ")
        parts = rest.split()
        if head not in table or len(parts) < 2:
            continue
        name, kind = parts[0], parts[1]
        if kind == "U":
            table[head][1].add(name)
        elif kind.isupper() or kind in "uvw":  # external definitions (weak ones too)
            table[head][0].add(name)
    return table


def call_graph(nm, src, objects):
    objects = [o for o in objects if os.path.exists(os.path.join(src, source_of(o)))]  # not generated or stale
    defs, undefs = {}, {}
    for obj, (d, u) in symbols(nm, objects).items():
        f = source_of(obj)
        undefs[f] = u
        for name in d:
            defs[name] = f
    graph = {f: collections.defaultdict(list) for f in undefs}
    for f, u in undefs.items():
        for name in sorted(u):
            g = defs.get(name)
            if g and g != f:
                graph[f][g].append(name)
    return graph


def loops(graph):
    """Strongly connected components of two or more files (Tarjan, iterative)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def one_cycle(graph, comp):
    """A shortest cycle through the loop's first file, as 'a -> b (sym) -> ... -> a (sym)'."""
    members, start = set(comp), comp[0]
    prev, queue = {start: None}, collections.deque([start])
    while queue:
        v = queue.popleft()
        for w in sorted(graph[v]):
            if w not in members:
                continue
            if w == start:
                path = [v]
                while prev[path[-1]] is not None:
                    path.append(prev[path[-1]])
                path.reverse()
                text = start
                for a, b in zip(path, path[1:] + [start]):
                    text += " -> %s (%s)" % (b, graph[a][b][0])
                return text
            if w not in prev:
                prev[w] = v
                queue.append(w)
    return " ".join(comp)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--nm", default="nm")
    ap.add_argument("--src", required=True)
    ap.add_argument("objects", nargs="+")
    a = ap.parse_args()
    try:
        graph = call_graph(a.nm, a.src, a.objects)
    except (OSError, subprocess.CalledProcessError) as e:
        print("file_circles: skipped: cannot read the objects with %s (%s)" % (a.nm, e))
        return 77
    if len(graph) < 50:
        print("file_circles: only %d object files of known sources: wrong arguments?" % len(graph), file=sys.stderr)
        return 1
    bad = 0
    for comp in loops(graph):
        bad += 1
        print("file_circles: FAIL: a loop of %d files: %s\n  all of them: %s" % (len(comp), one_cycle(graph, comp),
                                                                              " ".join(comp)), file=sys.stderr)
    edges = sum(len(v) for v in graph.values())
    if bad:
        print("file_circles: %d loop(s) of files that call each other (%d files, %d file-to-file calls); call "
              "downward only" % (bad, len(graph), edges), file=sys.stderr)
        return 1
    print("file_circles: %d files, %d file-to-file calls, no loop" % (len(graph), edges))
    return 0


if __name__ == "__main__":
    sys.exit(main())

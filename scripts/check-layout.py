#!/usr/bin/env python3
"""Checks the shape of rayfarm's source tree; run by ctest as `source_layout`.

    scripts/check-layout.py [--max-lines N] [--root DIR]

1. The include graph has no cycle. A node is a module: a header and the source file of the same
   name (x.h and x.cpp) are one node, so that x.cpp including y.h while y.cpp includes x.h is a
   cycle, even though no header includes itself. Only project includes ("folder/file.h", resolved
   from the repository root or the including file's folder) count.
2. No source file of the programs (common/, master/, worker/, cli/) is longer than N lines
   (default 500). Tests, benchmarks and fuzzers are not held to it.

Prints each cycle (as a chain of modules) and each long file, and exits 1 when there is any,
0 when the tree is clean, 2 on a usage error.
"""

import argparse
import os
import re
import sys

SOURCE_DIRS = ("common", "master", "worker", "cli")
CHECKED_DIRS = SOURCE_DIRS + ("proto", "tests", "bench", "fuzz")
EXTENSIONS = (".h", ".hpp", ".cpp", ".cc")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.MULTILINE)


def module_of(path):
    """The module a file belongs to: its path without the extension."""
    return os.path.splitext(path)[0]


def source_files(root):
    for top in CHECKED_DIRS:
        for folder, _, names in os.walk(os.path.join(root, top)):
            for name in sorted(names):
                if name.endswith(EXTENSIONS):
                    yield os.path.relpath(os.path.join(folder, name), root)


def resolve(root, including, target):
    for candidate in (target, os.path.join(os.path.dirname(including), target)):
        candidate = os.path.normpath(candidate)
        if os.path.isfile(os.path.join(root, candidate)):
            return candidate
    return None  # generated (proto/*.pb.h) or a system header written with quotes


def find_cycles(graph):
    """Every cycle found by a depth-first search, one chain per back edge."""
    cycles = []
    state = {}  # absent: unseen; 1: on the stack; 2: done
    stack = []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = 2

    sys.setrecursionlimit(10000)
    for node in sorted(graph):
        if node not in state:
            visit(node)
    return cycles


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-lines", type=int, default=500)
    parser.add_argument("--root", default=os.path.join(os.path.dirname(__file__), ".."))
    args = parser.parse_args()
    root = os.path.abspath(args.root)
    if not os.path.isdir(os.path.join(root, "common")):
        print(f"check-layout: {root} is not a rayfarm tree (no common/)", file=sys.stderr)
        return 2

    graph = {}
    long_files = []
    files = list(source_files(root))
    for path in files:
        with open(os.path.join(root, path), encoding="utf-8", errors="replace") as f:
            text = f.read()
        node = module_of(path)
        edges = graph.setdefault(node, set())
        for target in INCLUDE.findall(text):
            resolved = resolve(root, path, target)
            if resolved and module_of(resolved) != node:
                edges.add(module_of(resolved))
        lines = text.count("\n")
        if path.split(os.sep)[0] in SOURCE_DIRS and lines > args.max_lines:
            long_files.append((lines, path))

    cycles = find_cycles(graph)
    for cycle in cycles:
        print("include cycle: " + " -> ".join(cycle))
    for lines, path in sorted(long_files, reverse=True):
        print(f"too long: {path} has {lines} lines (at most {args.max_lines})")
    print(f"check-layout: {len(files)} files, {len(graph)} modules, {len(cycles)} include cycles, "
          f"{len(long_files)} files over {args.max_lines} lines")
    return 1 if cycles or long_files else 0


if __name__ == "__main__":
    sys.exit(main())

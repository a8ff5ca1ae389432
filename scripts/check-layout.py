#!/usr/bin/env python3
"""Checks the shape of rayfarm's source tree; run by ctest as `source_layout`.

    scripts/check-layout.py [--max-lines N] [--root DIR]

1. The include graph has no cycle. A node is a module: a header and the source file of the same
   name (x.h and x.cpp) are one node, so that x.cpp including y.h while y.cpp includes x.h is a
   cycle, even though no header includes itself. Only project includes ("folder/file.h", resolved
   from the repository root or the including file's folder) count.
2. No source file of the programs (common/, renderer/, master/, worker/, cli/) is longer than N lines
   (default 500). Tests, benchmarks and fuzzers are not held to it.

Prints each cycle (as a chain of modules) and each long file, and exits 1 when there is any,
0 when the tree is clean, 2 on a usage error. `--self-test` checks the checker on small trees
made on the spot (a clean one, one with a cycle through a .cpp, one with a long file).
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile

SOURCE_DIRS = ("common", "renderer", "master", "worker", "cli")
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


def self_test():
    """Runs this script on three small trees and checks its verdicts; returns the exit code."""
    trees = {
        "clean": ({"common/a.h": '#include "common/b.h"\n', "common/a.cpp": '#include "common/a.h"\n',
                   "common/b.h": "", "master/m.cpp": '#include "common/a.h"\n'}, 0, "0 include cycles"),
        "cycle": ({"common/a.h": "", "common/a.cpp": '#include "common/b.h"\n',
                   "common/b.h": "", "common/b.cpp": '#include "a.h"\n'}, 1,
                  "include cycle: common/a -> common/b -> common/a"),
        "long": ({"worker/w.cpp": "x\n" * 12, "tests/t.cpp": "x\n" * 50}, 1,
                 "too long: worker/w.cpp has 12 lines (at most 10)"),
    }
    failures = 0
    for name, (files, want_code, want_text) in trees.items():
        with tempfile.TemporaryDirectory() as root:
            os.makedirs(os.path.join(root, "common"), exist_ok=True)
            for path, text in files.items():
                os.makedirs(os.path.dirname(os.path.join(root, path)), exist_ok=True)
                with open(os.path.join(root, path), "w", encoding="utf-8") as f:
                    f.write(text)
            run = subprocess.run([sys.executable, __file__, "--root", root, "--max-lines", "10"],
                                 capture_output=True, text=True, check=False)
            ok = run.returncode == want_code and want_text in run.stdout
            if name == "long" and "tests/t.cpp" in run.stdout:
                ok = False  # tests are not held to the limit
            print(f"self-test {name}: {'ok' if ok else 'FAILED'} (exit {run.returncode})")
            if not ok:
                print(run.stdout + run.stderr)
                failures += 1
    return 1 if failures else 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-lines", type=int, default=500)
    parser.add_argument("--root", default=os.path.join(os.path.dirname(__file__), ".."))
    parser.add_argument("--self-test", action="store_true")
    args = parser.parse_args()
    if args.self_test:
        return self_test()
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

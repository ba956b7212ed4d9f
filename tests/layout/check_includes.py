#!/usr/bin/env python3
"""The include rules of docs/design.md ("Layout"), checked on every C++ file of the project.

    python3 tests/layout/check_includes.py [REPO]      (ctest: layout.includes)

1. Each folder includes only the project folders its layer may use (a table below, from the
   design's "may depend on" column): no models/ into src/pipeline/ or preprocess/, no LibTorch in
   preprocess/, core, data or the torch-free pipeline libraries, nothing of src/cli/ outside it.
2. No cycle between files: the graph of `#include "..."` edges between the project's files has no
   cycle, and no two modules (a .hpp and its .cpp taken as one) include each other's files.
Exit 0 when both hold, 1 with one line per violation otherwise.
"""

import pathlib
import re
import sys

ROOT = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).parents[2])
SOURCES = ("core", "src", "models", "preprocess", "data", "python/src", "tests", "bench", "fuzz")
INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]', re.M)

# Folder (prefix of the path) -> project folders it may include; first match wins.
ALLOWED = [
    ("core/", {"core"}),
    ("preprocess/", {"core", "preprocess"}),
    ("data/", {"core", "preprocess", "data"}),
    ("models/", {"core", "models"}),
    ("src/pipeline/", {"core", "preprocess", "data", "models", "pipeline"}),
    ("src/cli/", {"core", "preprocess", "data", "models", "pipeline", "cli"}),
    ("python/src/", {"core", "preprocess", "data", "models", "pipeline", "python"}),
]
# Files that must build without LibTorch (BSMS_TORCH=OFF): no torch/ATen/c10 include.
TORCH_FREE = ("core/", "preprocess/", "data/")
TORCH_FREE_PIPELINE = {  # bsms_runs: the pipeline's torch-free library (src/pipeline/CMakeLists.txt)
    "runs/", "report/", "graphs/graph_cache", "experiments/solver_frontier_file",
}


def project_folder(include):
    head = include.split("/")[0]
    if head in ("core", "pipeline", "cli"):
        return head
    if head in ("preprocess", "models", "data"):
        return head
    return None


def resolve(include, including, files):
    """The project file an include names, or None (system and third-party headers)."""
    for base in (ROOT / "src", ROOT, including.parent):
        candidate = (base / include).resolve()
        if candidate in files:
            return candidate
    return None


def main():
    files = set()
    for folder in SOURCES:
        for path in (ROOT / folder).rglob("*"):
            if path.suffix in (".cpp", ".hpp", ".h", ".cc") and "build" not in path.parts:
                files.add(path.resolve())
    problems = []
    edges = {f: set() for f in files}
    for f in sorted(files):
        rel = f.relative_to(ROOT).as_posix()
        text = f.read_text(errors="replace")
        rule = next((allowed for prefix, allowed in ALLOWED if rel.startswith(prefix)), None)
        torch_free = rel.startswith(TORCH_FREE) or (
            rel.startswith("src/pipeline/") and
            any(rel[len("src/pipeline/"):].startswith(p) for p in TORCH_FREE_PIPELINE))
        for bracket, include in INCLUDE.findall(text):
            if torch_free and re.match(r"(torch|ATen|c10)/", include):
                problems.append(f"{rel}: includes <{include}> but must build without LibTorch")
            target = resolve(include, f, files) if bracket == '"' else None
            if target is None:
                continue
            edges[f].add(target)
            folder = project_folder(include)
            if rule is not None and folder is not None and folder not in rule:
                problems.append(f"{rel}: includes \"{include}\" ({folder}/ is not among "
                                f"{', '.join(sorted(rule))})")
    # File-level cycles: depth-first search with colours.
    colour, stack = {}, []

    def visit(node):
        colour[node] = 1
        stack.append(node)
        for nxt in sorted(edges[node]):
            if colour.get(nxt, 0) == 0:
                visit(nxt)
            elif colour[nxt] == 1:
                cycle = stack[stack.index(nxt):] + [nxt]
                problems.append("include cycle: " +
                                " -> ".join(p.relative_to(ROOT).as_posix() for p in cycle))
        stack.pop()
        colour[node] = 2

    sys.setrecursionlimit(10000)
    for node in sorted(files):
        if colour.get(node, 0) == 0:
            visit(node)
    # Module-level cycles: a header and its source taken as one module, two modules whose files
    # include each other's.
    module = lambda p: p.with_suffix("")
    module_edges = {}
    for f, targets in edges.items():
        for t in targets:
            if module(t) != module(f):
                module_edges.setdefault(module(f), set()).add(module(t))
    pairs = sorted({tuple(sorted((a, b))) for a, bs in module_edges.items() for b in bs
                    if a in module_edges.get(b, set())})
    for a, b in pairs:
        problems.append(f"modules include each other: {a.relative_to(ROOT)} <-> "
                        f"{b.relative_to(ROOT)}")
    for p in problems:
        print(p)
    print(f"{len(files)} files, {sum(len(t) for t in edges.values())} project includes, "
          f"{len(problems)} violations")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())

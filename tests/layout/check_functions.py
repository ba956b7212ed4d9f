#!/usr/bin/env python3
"""No function of the project's C++ sources longer than 100 lines (docs/design.md "Layout").

    python3 tests/layout/check_functions.py [REPO] [LIMIT]      (ctest: layout.functions)

Counts the lines of every function body defined at namespace scope (free functions, member
functions defined outside their class, templates), from its signature's first line to its closing
brace. Comments, strings and character literals are blanked first, so braces in them do not count;
tables (`... = {`) and class bodies are not functions. Exit 0 when none exceeds LIMIT (default
100), 1 with one line per function otherwise.
"""

import pathlib
import re
import sys

ROOT = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).parents[2])
LIMIT = int(sys.argv[2]) if len(sys.argv) > 2 else 100
FOLDERS = ("core", "preprocess", "data", "models", "src", "python/src")


def blank(text):
    """Comments, raw strings, strings and character literals replaced, line breaks kept."""
    keep_lines = lambda m: "\n" * m.group(0).count("\n")
    text = re.sub(r"//[^\n]*", "", text)
    text = re.sub(r"/\*.*?\*/", keep_lines, text, flags=re.S)
    text = re.sub(r'R"\((.*?)\)"', lambda m: '""' + keep_lines(m), text, flags=re.S)
    text = re.sub(r'"(\\.|[^"\\\n])*"', '""', text)
    return re.sub(r"'(\\.|[^'\\\n])*'", "''", text)


def long_functions(path):
    text = blank(path.read_text(errors="replace"))
    found = []
    braces = []  # one entry per open brace: True for a namespace's
    start, line, head, head_depth = 0, 1, None, 0
    for i, ch in enumerate(text):
        if ch == "\n":
            line += 1
        elif ch == "{":
            prefix = text[start:i]
            namespace = bool(re.search(r"\bnamespace\b[^;{}]*$", prefix) or
                             re.search(r'\bextern\s*""\s*$', prefix))
            at_scope = not any(not b for b in braces)  # only namespaces around it
            signature = prefix.split("(")[0]
            if (head is None and not namespace and at_scope and "(" in prefix and
                    not re.search(r"\b(class|struct|enum|union)\b", signature) and
                    not prefix.rstrip().endswith(("=", "]"))):
                head = (line - prefix.count("\n"), " ".join(prefix.split())[:90])
                head_depth = len(braces)
            braces.append(namespace)
            start = i + 1
        elif ch == "}":
            if braces:
                braces.pop()
            if head is not None and len(braces) == head_depth:
                length = line - head[0] + 1
                if length > LIMIT:
                    found.append((length, head[0], head[1]))
                head = None
            start = i + 1
        elif ch == ";":
            start = i + 1
    return found


def main():
    problems = []
    count = 0
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*")):
            if path.suffix not in (".cpp", ".hpp") or "build" in path.parts:
                continue
            count += 1
            for length, at, head in long_functions(path):
                problems.append(f"{path.relative_to(ROOT)}:{at}: {length} lines: {head}")
    for p in problems:
        print(p)
    print(f"{count} files, {len(problems)} functions over {LIMIT} lines")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""check_includes.py on small constructed trees: each broken rule fails with its own line, a clean
tree passes. (ctest: layout.includes_rules)"""

import pathlib
import subprocess
import sys
import tempfile

CHECK = pathlib.Path(__file__).with_name("check_includes.py")


def run(files):
    with tempfile.TemporaryDirectory() as root:
        for name, text in files.items():
            path = pathlib.Path(root) / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
        done = subprocess.run([sys.executable, str(CHECK), root], capture_output=True, text=True)
        return done.returncode, done.stdout


CLEAN = {
    "core/a.hpp": "#pragma once\n",
    "core/a.cpp": '#include "core/a.hpp"\n',
    "preprocess/p.hpp": '#pragma once\n#include "core/a.hpp"\n',
    "preprocess/p.cpp": '#include "preprocess/p.hpp"\n',
    "models/m.hpp": '#pragma once\n#include <torch/types.h>\n#include "core/a.hpp"\n',
}

CASES = {
    "file cycle": ({"core/b.hpp": '#include "core/c.hpp"\n', "core/c.hpp": '#include "core/b.hpp"\n'},
                   "include cycle: "),
    "module cycle": ({"core/d.hpp": "#pragma once\n", "core/d.cpp": '#include "core/e.hpp"\n',
                      "core/e.hpp": '#include "core/d.hpp"\n', "core/e.cpp": ""},
                     "modules include each other: core/d <-> core/e"),
    "models in preprocess": ({"preprocess/q.cpp": '#include "models/m.hpp"\n'},
                             'preprocess/q.cpp: includes "models/m.hpp"'),
    "torch in core": ({"core/t.cpp": "#include <ATen/Tensor.h>\n"},
                      "core/t.cpp: includes <ATen/Tensor.h> but must build without LibTorch"),
    "pipeline in models": ({"src/pipeline/x.hpp": "#pragma once\n",
                            "models/n.cpp": '#include "pipeline/x.hpp"\n'},
                           'models/n.cpp: includes "pipeline/x.hpp"'),
}


def main():
    failures = []
    code, out = run(CLEAN)
    if code != 0 or "0 violations" not in out:
        failures.append(f"clean tree: exit {code}\n{out}")
    for name, (extra, expected) in CASES.items():
        code, out = run({**CLEAN, **extra})
        if code != 1 or expected not in out:
            failures.append(f"{name}: exit {code}, expected a line with {expected!r}\n{out}")
    for f in failures:
        print(f)
    print(f"{len(CASES) + 1 - len(failures)} of {len(CASES) + 1} trees judged as expected")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env bash
# The README as a new user meets it (ctest docs.readme):
#  1. every relative link of README.md and docs/*.md names a file or folder of the repository;
#  2. every `make` target the README names exists (make -n);
#  3. the README's example commands (the ```sh blocks that call build/bsms, and the Python block)
#     run as written from a working folder holding the repository's configs/ and tests/, the
#     sizes shrunk (generate --trajectories 100 -> 4, train steps=2000 -> 3 with small validation)
#     so that the test takes seconds; each must exit 0 and leave its outputs.
# Usage: readme.sh SOURCE_DIR BUILD_DIR WORK_DIR
set -euo pipefail
src=$1 build=$2 work=$3
fail() { echo "readme: $*" >&2; exit 1; }

# 1. Links: [text](target), target not a URL or an anchor alone; and every repository path the
#    pages name in code spans (`docs/design.md`, `configs/...`); words with capitals or *, {}, <>
#    stand for a user's names and are skipped. docs/results.md, the log, may name files of its time.
/usr/bin/python3 - "$src" <<'PY' || exit 1
import pathlib, re, sys
root = pathlib.Path(sys.argv[1])
folders = ("docs/", "configs/", "scripts/", "src/", "core/", "tests/", "bench/", "data/", "models/",
           "preprocess/", "python/", "examples/", "fuzz/", ".ci/")
bad, checked = [], 0
for page in [root / "README.md", *sorted((root / "docs").glob("*.md"))]:
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+://|mailto:|#", target):
            continue
        checked += 1
        if not (page.parent / target.split("#")[0]).resolve().exists():
            bad.append(f"{page.relative_to(root)}: link to {target}: no such file")
    if page.name == "results.md":
        continue
    for span in re.findall(r"`([^`\n]+)`", text):
        for word in span.split():
            word = word.strip(".,;:()")
            if not word.startswith(folders) or re.search(r"[*{}<>]|[A-Z]{3,}", word):
                continue
            checked += 1
            if not (root / word).exists():
                bad.append(f"{page.relative_to(root)}: names {word}: no such file")
for b in bad:
    print(b)
print(f"readme: {checked} links and paths checked")
sys.exit(1 if bad else 0)
PY

# 2. make targets named in README code or text (`make NAME`).
for target in $(grep -o 'make [a-z][a-z-]*' "$src/README.md" | awk '{print $2}' | sort -u); do
  make -n -C "$src" "$target" >/dev/null 2>&1 || fail "README names 'make $target', which the Makefile does not have"
done

# 3. The example commands.
rm -rf "$work" && mkdir -p "$work/build"
cd "$work"
ln -s "$src/configs" configs
ln -s "$src/tests" tests
for program in bsms bsms-solver bsms-torch bsms-gmsh-worker; do ln -s "$build/$program" "build/$program"; done
ln -s "$build/python" build/python
commands=$(awk '/^```sh/{f=1; next} /^```/{f=0} f && /^build\/bsms /' "$src/README.md")
[ -n "$commands" ] || fail "no build/bsms example in README.md"
small=' --set steps=3 --set valid_every=3 --set valid_samples=2 --set normalizer_steps=2 --set optimizer.warmup_steps=1'
while IFS= read -r line; do
  line=${line%%#*}  # the comment after a command
  line=${line//--trajectories 100/--trajectories 4 --split 2:1:1 --threads 2}
  line=${line//--set steps=2000/$small}
  if [[ $line == *" simulate "* ]]; then line="$line --set solver.end_time=0.02"; fi
  echo "+ $line"
  eval "$line" >/dev/null 2>"$work/stderr" || { cat "$work/stderr" >&2; fail "README command failed: $line"; }
done <<<"$commands"
for made in runs/plate.h5 runs/disks/frames.h5 runs/data/disks2d/test.h5 runs/bsms/rollout/metrics.json \
            runs/mgn/rollout/metrics.json runs/report/report.md runs/bsms/rollout-closecenter/metrics.json \
            runs/bsms/rollout_one_step/metrics.json runs/seeding/metrics.json; do
  [ -e "$made" ] || fail "a README command did not write $made"
done
# The Python block, as written (its paths relative to this folder, like the repository root).
python_block=$(awk '/^PYTHONPATH=build\/python/{f=1} f{print} f && /'"'"'\)?$/ && !/^PYTHONPATH/{exit}' "$src/README.md")
[ -n "$python_block" ] || fail "no Python example in README.md"
echo "+ (the Python example)"
eval "$python_block" >/dev/null || fail "the README's Python example failed"
echo "readme: links, make targets and $(wc -l <<<"$commands") example commands and the Python example ran"

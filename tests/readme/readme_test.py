#!/usr/bin/env python3
"""README.md is the contract: every ```sh block runs as written, in order, in one shell (as a newcomer pastes them),
in a fresh directory that looks like the checkout (data/, scripts/ and build/ linked in), in a clean environment
(the README itself puts the built topocal on PATH). A block is left out only when the line before its fence says so:

    <!-- readme-test: skip: REASON -->

(the set-up commands at the top, which install packages and are what CI itself runs; the development block, which
builds and runs ctest and would run this test inside itself). `cmake --install` goes into DESTDIR under the work
directory, never into the machine. Each block's time is printed: a block too slow for CI shows here, not hidden.

usage: readme_test.py SOURCE_DIR BINARY_DIR WORK_DIR
"""
import os
import re
import shutil
import subprocess
import sys
import time

SOURCE, BINARY, WORK = (os.path.abspath(p) for p in sys.argv[1:4])
MARKER = re.compile(r"<!--\s*readme-test:\s*skip:\s*(.+?)\s*-->")

with open(os.path.join(SOURCE, "README.md")) as f:
    lines = f.read().split("\n")

blocks, skipped = [], []
i = 0
while i < len(lines):
    if lines[i].strip() == "```sh":
        start = i
        j = i + 1
        while lines[j].strip() != "```":
            j += 1
        before = next((lines[k] for k in range(start - 1, -1, -1) if lines[k].strip()), "")
        marker = MARKER.search(before)
        (skipped if marker else blocks).append((start + 1, "\n".join(lines[start + 1:j]),
                                                marker.group(1) if marker else ""))
        i = j
    i += 1

shutil.rmtree(WORK, ignore_errors=True)
os.makedirs(os.path.join(WORK, "home"))
for name in ("data", "scripts"):
    os.symlink(os.path.join(SOURCE, name), os.path.join(WORK, name))
os.symlink(BINARY, os.path.join(WORK, "build"))
# A clean environment, as a new root shell on a fresh Debian machine has it: nothing of the developer's or of this
# test's own (the README must put the built CLI on PATH itself), save DESTDIR, which keeps `cmake --install` out of
# the machine, and HOME, a fresh one.
env = {"PATH": "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin", "LANG": "C.UTF-8",
       "DESTDIR": os.path.join(WORK, "destdir"), "HOME": os.path.join(WORK, "home")}

for line, _, reason in skipped:
    print(f"README line {line}: skipped ({reason})")
# One shell for all blocks, so that an `export` in one holds in the next, as when pasted in order.
script = ["set -euo pipefail"]
for n, (line, text, _) in enumerate(blocks):
    script += [f'echo "== README block at line {line}" >&2', f"block_start=$SECONDS", text,
               f'echo "== README block at line {line}: $((SECONDS - block_start)) s" >&2']
t0 = time.time()
r = subprocess.run(["bash", "-c", "\n".join(script)], cwd=WORK, env=env, capture_output=True, text=True)
timings = [l for l in r.stderr.splitlines() if l.startswith("== README block") and l.endswith(" s")]
print("\n".join(timings))
print(f"{len(blocks)} blocks in {time.time() - t0:.0f} s")
if r.returncode != 0:
    failed = [l for l in r.stderr.splitlines() if l.startswith("== README block")][-1]
    print(f"FAIL: exit {r.returncode} in {failed.removeprefix('== ')}\n--- stderr (end) ---\n{r.stderr[-4000:]}"
          f"\n--- stdout (end) ---\n{r.stdout[-2000:]}", file=sys.stderr)
    sys.exit(1)
if len(skipped) != 2:  # the set-up block at the top and the development block
    print(f"FAIL: {len(skipped)} blocks skipped; only the set-up and development blocks may be", file=sys.stderr)
    sys.exit(1)
shutil.rmtree(WORK, ignore_errors=True)

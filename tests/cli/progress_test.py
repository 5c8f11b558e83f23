#!/usr/bin/env python3
"""Progress lines: drawn on stderr when it is a terminal (a pseudo-terminal here), never in a pipe or log, never
with --quiet; the verb's own output is unchanged either way.

usage: progress_test.py TOPOCAL_EXE WORK_DIR
"""
import os
import shutil
import subprocess
import sys

TOPOCAL, WORK = os.path.abspath(sys.argv[1]), sys.argv[2]
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAIL:", what, file=sys.stderr)


shutil.rmtree(WORK, ignore_errors=True)
os.makedirs(WORK)
with open(os.path.join(WORK, "board.yaml"), "w") as f:
    f.write("target_type: checkerboard\ntargetCols: 9\ntargetRows: 7\nrowSpacingMeters: 0.002\ncolSpacingMeters: 0.002\n")
# A render of ~3 s of wall time on 2 cores (the edges sub-sampled 24 x 24): well beyond the 1 s before the first
# progress line even on a faster machine (a render near 1 s would draw the line only under load).
render = [TOPOCAL, "render-target", "--target", "board.yaml", "--width", "4000", "--height", "3000", "--focal-mm",
          "5.2", "--pixel-pitch-um", "3", "--distance-mm", "70", "--supersampling", "24", "--out", "view.png"]


def stderr_on_terminal(args):
    master, slave = os.openpty()
    p = subprocess.Popen(args, cwd=WORK, stdout=subprocess.PIPE, stderr=slave)
    os.close(slave)
    err = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        err += chunk
    out = p.communicate()[0]
    os.close(master)
    check(p.returncode == 0, f"{' '.join(args[1:3])}: exit {p.returncode}")
    return out.decode(), err.decode()


out, err = stderr_on_terminal(render)
check("topocal render-target: rendering 4000 x 3000 ..." in err, f"progress drawn on a terminal: {err!r}")
check(err.rstrip().endswith("\x1b[K") or "\r\x1b[K" in err, f"progress line erased at the end: {err!r}")
check("view.png" in out and "rendering" not in out, f"stdout unchanged: {out!r}")
out_quiet, err_quiet = stderr_on_terminal(render[:1] + ["--quiet"] + render[1:])
check("rendering" not in err_quiet, f"--quiet: no progress: {err_quiet!r}")
check(out_quiet == out, "--quiet: same stdout")
r = subprocess.run(render, cwd=WORK, capture_output=True, text=True)
check(r.returncode == 0 and "rendering" not in r.stderr, f"stderr a pipe: no progress: {r.stderr!r}")

if failures:
    print(f"{len(failures)} check(s) failed", file=sys.stderr)
    sys.exit(1)
shutil.rmtree(WORK, ignore_errors=True)
print("progress only on a terminal")

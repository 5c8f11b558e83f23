#!/usr/bin/env python3
"""Kills `topocal unit calibrate` at random moments and counts how each run ended (docs/robustness.md, "Signals").

Each run calibrates the test suite's unit (build/test-data/unit-inputs-v2, written by the first `ctest` run) into a
fresh directory, waits until its staging directory SN.tmp-PID-TOKEN appears (the record is being written) or, with
--anytime, for a random moment of the whole run, sleeps a further random 0..MAX ms and sends the signal. A run must
end either by the signal (nothing left in the directory) or normally with exit code 0 (the whole record left). Any
other ending or anything else left behind is printed and counted as a failure; the exit code is 1 if there was one.

Usage: python3 bench/signal_kills.py [--runs N] [--max-delay-ms MAX] [--signal TERM|INT|HUP] [--anytime] [--seed S]
"""
import argparse
import collections
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--max-delay-ms", type=float, default=50.0)
    ap.add_argument("--signal", choices=["TERM", "INT", "HUP"], default="TERM")
    ap.add_argument("--anytime", action="store_true", help="kill at a random moment of the run, not of the writing")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--topocal", default=os.path.join(root, "build/tools/topocal"))
    ap.add_argument("--inputs", default=os.path.join(root, "build/test-data/unit-inputs-v2"))
    a = ap.parse_args()
    for path in (a.topocal, os.path.join(a.inputs, "target.yaml")):
        if not os.path.exists(path):
            sys.exit(f"signal_kills: {path}: missing (build topocal and run ctest once)")
    rng = random.Random(a.seed)
    sig = getattr(signal, "SIG" + a.signal)
    outcomes = collections.Counter()
    failures = 0
    work = tempfile.mkdtemp(prefix="topocal-kills-")
    try:
        for _ in range(a.runs):
            shutil.rmtree(work, ignore_errors=True)
            os.makedirs(work)
            out = os.path.join(work, "SN")
            i = a.inputs
            p = subprocess.Popen([a.topocal, "unit", "calibrate", "--serial", "SN", "--target", f"{i}/target.yaml",
                                  "--images", f"{i}/view.png", "--reference-sphere", f"{i}/sphere.png",
                                  "--sphere-radius-mm", "7.8", "--device", f"{i}/device.json", "--uncertainty", "8",
                                  "--out", out], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
            if a.anytime:
                time.sleep(rng.uniform(0, 2.0))
            else:
                staging = f"SN.tmp-{p.pid}-"  # then an unpredictable token
                while not any(n.startswith(staging) for n in os.listdir(work)) and p.poll() is None:
                    time.sleep(0.0002)
                time.sleep(rng.uniform(0, a.max_delay_ms) / 1000)
            p.send_signal(sig)
            _, err = p.communicate()
            left = sorted(os.listdir(work))
            ok = (p.returncode == -sig and not left) or (p.returncode == 0 and left == ["SN"])
            ending = f"signal {-p.returncode}" if p.returncode < 0 else f"exit {p.returncode}"
            outcomes[(ending, " ".join(left) or "nothing left")] += 1
            if not ok:
                failures += 1
                print(f"FAIL: {ending}, left: {left}, stderr: {err.decode(errors='replace').strip()[:200]}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    for (ending, left), n in sorted(outcomes.items()):
        print(f"{n:5d}  ended by {ending}, {left}")
    print(f"{failures} failure(s) in {a.runs} runs")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

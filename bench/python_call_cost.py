#!/usr/bin/env python3
"""The cost of a measurement from Python beside the CLI's (docs/performance.md, "Python").

Renders the demo unit's eye (4000 x 3000) once, then times, in the same run, N repeats of
  cli:    `topocal reconstruct --config paper.json --image eye.png --device demo-unit-device.json --json out.json`
          (a process: start-up, codec loading, PNG decoding, the measurement, the JSON written)
  python: topocal.reconstruct(config, device=device, image=array) on the decoded image (the measurement alone),
          and cv2.imread of the same PNG (the decoding a Python caller does itself).
Wall and CPU seconds per call (CPU: the process's own for Python, the children's for the CLI), median of N.

Usage: PYTHONPATH=build/python /usr/bin/python3 bench/python_call_cost.py [--repeats N] [--cli build/tools/topocal]
"""
import argparse
import os
import resource
import statistics
import subprocess
import tempfile
import time

import cv2

import topocal


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed(fn, cpu_clock):
    w0, c0 = time.perf_counter(), cpu_clock()
    fn()
    return time.perf_counter() - w0, cpu_clock() - c0


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--cli", default=os.path.join(root, "build", "tools", "topocal"))
    a = ap.parse_args()
    data = os.path.join(root, "data")
    paper, device_file = os.path.join(data, "paper.json"), os.path.join(data, "demo-unit-device.json")
    with tempfile.TemporaryDirectory() as work:
        eye = os.path.join(work, "eye.png")
        subprocess.run([a.cli, "render-spots", "--config", paper, "--device", device_file, "--out", eye], check=True,
                       stdout=subprocess.DEVNULL)
        config, device = topocal.Config.load(paper), topocal.Device.load(device_file)
        image = cv2.imread(eye, cv2.IMREAD_UNCHANGED)
        cli = [a.cli, "--quiet", "reconstruct", "--config", paper, "--image", eye, "--device", device_file, "--json",
               os.path.join(work, "out.json")]
        rows = {
            "CLI reconstruct (process, PNG decoded, JSON written)":
                lambda: subprocess.run(cli, check=True, stdout=subprocess.DEVNULL),
            "topocal.reconstruct (in process, decoded image)":
                lambda: topocal.reconstruct(config, device=device, image=image),
            "cv2.imread of the PNG (the caller's decoding)": lambda: cv2.imread(eye, cv2.IMREAD_UNCHANGED),
        }
        print(f"median of {a.repeats} calls, load {os.getloadavg()[0]:.2f}, {os.cpu_count()} cores")
        print(f"{'call':<56} {'wall s':>8} {'CPU s':>8}")
        for name, fn in rows.items():
            clock = children_cpu if name.startswith("CLI") else time.process_time
            fn()  # warm: the first call loads what later calls reuse
            samples = [timed(fn, clock) for _ in range(a.repeats)]
            print(f"{name:<56} {statistics.median(s[0] for s in samples):8.3f} "
                  f"{statistics.median(s[1] for s in samples):8.3f}")


if __name__ == "__main__":
    main()

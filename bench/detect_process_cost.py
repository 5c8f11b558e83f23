#!/usr/bin/env python3
"""What a `topocal detect` process costs, beside OpenCV-Python doing the shared part of its work in the same run.

Figures, each the CPU time (user + system, every thread) of N runs, interleaved so that all see the same machine:
  /bin/true          any process on this machine (the floor)
  detect, blank      `topocal detect` of a blank 4000 x 3000 frame: the process' fixed cost (start-up, loading,
                     decoding a frame, one pass of the detector over it; the spot search finds nothing: exit 4)
  detect, spots      `topocal detect` of the noisy 4000 x 3000 PNG that `render-spots` makes of the paper's pattern
                     (16-bit, read noise 60 DN, shot noise): the whole command
  cv2 peer           cv2.imread + cv2.threshold + cv2.connectedComponentsWithStats of the same PNG, in this process
                     (warm: Python and OpenCV already loaded; each call allocates its arrays anew), with OpenCV's
                     default threads and with one; the ratio is taken to the cheaper of the two
  cv2.imread, blank  decoding the blank frame alone, in this process: the part of the fixed cost any reader pays
  [before]           the same two detects with a second binary (--before), e.g. main's build
The targets printed beside them: the blank frame <= 20 ms, the whole detect <= 1.5x the peer.

Usage: /usr/bin/python3 bench/detect_process_cost.py [--repeats N] [--topocal BIN] [--before BIN]
(Debian's python3-opencv: /usr/bin/python3; the frames are rendered once into build/detect-bench/.)
"""
import argparse
import os
import resource
import statistics
import subprocess
import sys
import time

import cv2
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def child_cpu(cmd, ok_codes=(0,)):
    """CPU seconds (user + system) of one process running cmd, from its own rusage."""
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    code = os.waitstatus_to_exitcode(status)
    if code not in ok_codes:
        sys.exit(f"{' '.join(cmd)}: exit {code}")
    return usage.ru_utime + usage.ru_stime


def self_cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def peer(path, threshold):
    """cv2.imread + threshold + connected components with their statistics: CPU seconds and the component count."""
    t0 = self_cpu()
    image = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    _, mask = cv2.threshold(image, threshold, 255, cv2.THRESH_BINARY)  # 16-bit in, 16-bit 0 / 255 out
    count, _, _, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8, copy=False), connectivity=8)
    return self_cpu() - t0, count - 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--topocal", default=os.path.join(ROOT, "build/tools/topocal"))
    ap.add_argument("--before", help="a second topocal binary, run interleaved")
    ap.add_argument("--threshold", type=float, default=1000 + 8 * 60,
                    help="the peer's threshold, DN (default: background + 8 sigma of the rendered read noise)")
    args = ap.parse_args()
    os.environ.setdefault("TOPOCAL_DATA_DIR", os.path.join(ROOT, "data"))
    work = os.path.join(ROOT, "build/detect-bench")
    os.makedirs(work, exist_ok=True)
    device, config = os.path.join(ROOT, "data/device.json"), os.path.join(ROOT, "data/paper.json")
    spots, blank = os.path.join(work, "spots.png"), os.path.join(work, "blank.png")
    if not os.path.exists(spots):
        subprocess.run([args.topocal, "render-spots", "--config", config, "--device", device, "--sigma", "0",
                        "--out", spots], check=True, stdout=subprocess.DEVNULL)
    if not os.path.exists(blank):  # the same sensor, nothing in front of it: the background level, 16-bit
        cv2.imwrite(blank, np.full((3000, 4000), 1000, np.uint16))

    def detect(binary, image, ok_codes):
        return [binary, "detect", "--image", image, "--device", device, "--config", config,
                "--out", os.path.join(work, "out.csv"), "--json", os.path.join(work, "out.json")], ok_codes

    figures = {"/bin/true": (["/bin/true"], (0,)),
               "detect, blank": detect(args.topocal, blank, (4,)),
               "detect, spots": detect(args.topocal, spots, (0,))}
    if args.before:
        figures["before: detect, blank"] = detect(args.before, blank, (4,))
        figures["before: detect, spots"] = detect(args.before, spots, (0,))
    threads = cv2.getNumThreads()
    peers = {f"cv2 peer, {threads} threads": threads, "cv2 peer, 1 thread": 1}
    times = {name: [] for name in list(figures) + list(peers) + ["cv2.imread, blank"]}
    load = os.getloadavg()
    peer(spots, args.threshold)  # the first call pays OpenCV's first-use costs once, as a long-lived caller would
    components = 0
    for _ in range(args.repeats):
        for name, (cmd, ok_codes) in figures.items():
            times[name].append(child_cpu(cmd, ok_codes))
        for name, n in peers.items():
            cv2.setNumThreads(n)
            cpu, components = peer(spots, args.threshold)
            times[name].append(cpu)
        cv2.setNumThreads(threads)
        t0 = self_cpu()
        cv2.imread(blank, cv2.IMREAD_UNCHANGED)
        times["cv2.imread, blank"].append(self_cpu() - t0)
    load = (load, os.getloadavg())

    def ms(name):
        v = times[name]
        return statistics.median(v) * 1e3, min(v) * 1e3, max(v) * 1e3

    print(f"load {load[0][0]:.2f} -> {load[1][0]:.2f} (2 cores), {args.repeats} runs each, CPU ms: median (min-max)")
    print(f"binary {args.topocal}" + (f", before {args.before}" if args.before else ""))
    print(f"cv2 {cv2.__version__}; peer threshold {args.threshold:g} DN: {components} components\n")
    print("| figure | CPU ms | limit |")
    print("|---|---:|---|")
    # The peer's cheaper run (OpenCV's idle workers spin on a loaded machine, which costs CPU, not work).
    peer_ms = min(ms(name)[0] for name in peers)
    for name in times:
        med, lo, hi = ms(name)
        limit = ""
        if name.endswith("detect, blank"):
            limit = f"<= 20 ms: {'met' if med <= 20 else 'not met'}"
        elif name.endswith("detect, spots"):
            limit = f"{med / peer_ms:.2f}x the peer (<= 1.5x: {'met' if med <= 1.5 * peer_ms else 'not met'})"
        print(f"| {name} | {med:.1f} ({lo:.1f}-{hi:.1f}) | {limit} |")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The figures of docs/performance.md, measured again in one run: each beside its peer (measured in the same run) or
its limit, as a markdown table with the machine's load.

The in-process figures come from the Google Benchmark binaries (their JSON output: the median of --repeats runs);
the whole-process figures (`unit calibrate`, a `detect` process) from bench/process_timings.sh and
bench/detect_process_cost.py; with --scale, the fleet and harness scale runs too (minutes, gigabytes under /tmp).

usage: /usr/bin/python3 bench/figures.py [--repeats N] [--build DIR] [--scale]
"""
import argparse
import json
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (binary, benchmark, label, peer benchmark or None, limit in ms or None, "x peer" limit or None)
IN_PROCESS = [
    ("bench_topo", "BM_PaperSweepOneThread", "paper 7-sigma sweep in process, one thread", None, 20.0, None),
    ("bench_harness", "BM_HarnessCase", "a harness case (3e4 cases/min/core = 2 ms)", None, 2.0, None),
    ("bench_correct", "BM_UndistortOneShot/real_time", "one-shot undistortion of a 4000 x 3000 image",
     "BM_CvUndistort/real_time", None, 1.0),
    ("bench_calib", "BM_SolveTopocal/0", "chessboard calibration of OpenCV's 13 photographs (solve)",
     "BM_SolveOpenCv", None, 1.0),
    ("bench_calib_detection", "BM_RenderUnitTarget/0/real_time", "render-target 4000 x 3000 in process (wall)",
     "BM_RenderUnitTargetOpenCv/real_time", 2000.0, None),
    ("bench_device", "BM_DeviceCalibrationThreeBalls", "device calibration from three balls, detection included",
     "BM_OpenCvCalibrateCameraThreeViews", 1000.0, None),
    ("bench_device", "BM_DeviceFitThreeBallsAndFiveTargetViews", "device fit, three balls and five target views",
     "BM_OpenCvCalibrateCameraFiveTargetViews", None, None),
    ("bench_device", "BM_MeasureEyeWithUncertainty/1/process_time/real_time",
     "a measurement through a device with every number's U (CPU)", "BM_MeasureEyeThroughDevice/process_time/real_time",
     None, 1.5),
    ("bench_imageio", "BM_DecodePng_Topocal/2", "decoding a noisy 4000 x 3000 16-bit PNG in process",
     "BM_DecodePng_OpenCvImdecode/2", None, 1.0),
]


def load():
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def benchmark_medians(build, binary, names, repeats):
    """Median time (ms) of each named benchmark of one binary: CPU time, or real time for /real_time ones."""
    pattern = "^(" + "|".join(re.escape(n) for n in names) + ")$"
    out = subprocess.run([os.path.join(build, "bench", binary), f"--benchmark_filter={pattern}",
                          f"--benchmark_repetitions={repeats}", "--benchmark_report_aggregates_only=true",
                          "--benchmark_format=json"], capture_output=True, text=True, check=True).stdout
    medians = {}
    for b in json.loads(out)["benchmarks"]:
        # The median of the repetitions; a single repetition is reported as the run itself.
        if b.get("aggregate_name") != "median" and not (repeats == 1 and b.get("run_type") == "iteration"):
            continue
        scale = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}[b["time_unit"]]
        name = b["run_name"]
        key = "real_time" if "/real_time" in name and "/process_time" not in name else "cpu_time"
        medians[b["run_name"]] = b[key] * scale
    return medians


def verdict(now, peer, limit_ms, limit_ratio):
    checks = []
    if limit_ms is not None:
        checks.append(now <= limit_ms)
    if limit_ratio is not None and peer is not None:
        checks.append(now <= limit_ratio * peer)
    if not checks:
        return "—"
    return "met" if all(checks) else "NOT met"


def in_process_rows(build, repeats):
    rows = []
    by_binary = {}
    for entry in IN_PROCESS:
        by_binary.setdefault(entry[0], []).append(entry)
    for binary, entries in by_binary.items():
        names = [e[1] for e in entries] + [e[3] for e in entries if e[3]]
        medians = benchmark_medians(build, binary, names, repeats)
        for _, name, label, peer_name, limit_ms, limit_ratio in entries:
            now = medians[name]
            peer = medians.get(peer_name) if peer_name else None
            limit = " and ".join(x for x in [f"<= {limit_ms:g} ms" if limit_ms is not None else "",
                                             f"<= {limit_ratio:g} x peer" if limit_ratio is not None else ""] if x)
            rows.append([f"{label} (`{binary}` {name})", f"{now:.3g} ms",
                         f"{peer:.3g} ms ({peer_name})" if peer is not None else "—", limit or "—",
                         verdict(now, peer, limit_ms, limit_ratio)])
    return rows


def process_rows(build, repeats):
    """`unit calibrate` of the demo unit and the fixed cost of a detect process, by their own scripts."""
    rows = []
    table = subprocess.run(["bash", os.path.join(ROOT, "bench/process_timings.sh"), str(repeats),
                            os.path.join(build, "tools/topocal")], capture_output=True, text=True, check=True).stdout
    cells = {}
    for line in table.splitlines():
        parts = [p.strip() for p in line.strip().strip("|").split("|")]
        if len(parts) == 2:
            cells[parts[0]] = parts[1]
    unit = cells.get("topocal unit calibrate (demo unit)", "?")
    opencv_peer = cells.get("OpenCV calibration of the unit's target view (peer)", "?")
    cpu = float(unit.split("/")[1]) if unit.count("/") == 2 else float("nan")
    rss = float(unit.split("/")[2]) if unit.count("/") == 2 else float("nan")
    rows.append(["`unit calibrate` of the demo unit, wall s / CPU s / peak MB (`process_timings.sh`)", unit,
                 "OpenCV's calibration of the same target view " + opencv_peer,
                 "<= 1.0 s CPU, <= 200 MB",
                 "met" if cpu <= 1.0 and rss <= 200 else "NOT met"])
    detect = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "bench/detect_process_cost.py"), "--repeats",
                             str(repeats), "--topocal", os.path.join(build, "tools/topocal")],
                            capture_output=True, text=True)
    if detect.returncode != 0:
        rows.append(["a `detect` process (`detect_process_cost.py`)", "failed: " + detect.stderr.strip()[-200:],
                     "—", "—", "—"])
    for line in detect.stdout.splitlines():  # its own table: figure | CPU ms | limit (the peers are rows of it)
        parts = [p.strip() for p in line.strip().strip("|").split("|")]
        if len(parts) == 3 and line.startswith("|") and parts[0] != "figure" and not parts[0].startswith("---"):
            rows.append([f"{parts[0]} (`detect_process_cost.py`, CPU)", f"{parts[1]} ms", "its rows", parts[2] or "—",
                         "—"])
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    parser.add_argument("--scale", action="store_true", help="also the fleet and harness scale runs (long)")
    parser.add_argument("--no-process", action="store_true", help="only the in-process benchmarks")
    args = parser.parse_args()
    print(f"load before: {load()}   repeats: {args.repeats}   build: {args.build}\n")
    rows = in_process_rows(args.build, args.repeats)
    if not args.no_process:
        rows += process_rows(args.build, args.repeats)
    print("| figure | now | peer, same run | limit | |")
    print("|---|---:|---|---|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")
    if args.scale:
        subprocess.run(["bash", os.path.join(ROOT, "bench/fleet_scale.sh"), "1000 10000 100000", "3"], check=True)
        subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "bench/harness_scale.py")], check=True)
    print(f"\nload after: {load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

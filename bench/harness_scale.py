#!/usr/bin/python3
"""The harness beyond one machine (docs/scale-out.md): for 1e3, 1e4, 1e5 (and, asked for, 1e6) cases, a single run and
a sharded run through scripts/cluster/harness-array.sbatch as a Slurm array runs it (SLURM_ARRAY_TASK_ID /
SLURM_ARRAY_TASK_COUNT; here many local processes, --slots at a time), the merge through
scripts/cluster/harness-merge.sbatch, and `cmp` of every merged file with the single run's. Prints cases/min/core
(CPU time of the processes, from getrusage of the children), the merge's wall and CPU time and peak RSS, and the
output sizes, each beside its limit; with --merge-1000, a 1,000-shard run of the largest size and its merge; with
--runner k8s, the tasks run the container command of scripts/cluster/harness-indexed-job.yaml instead
(JOB_COMPLETION_INDEX, SHARDS = the number of tasks).

  nice -n 19 /usr/bin/python3 bench/harness_scale.py --topocal build/tools/topocal --work /tmp/harness-scale-data/bench
  ... --sizes 1e6 --shards 1000            # the million-case run (~30 CPU-minutes per pass at 1.8 ms per case)

The cases are data/harness.json's (3 corneas x 30 distortions x 6 calibration errors) with noise_draws set for the
size: 2, 19, 185, 1852 draws -> 1,080, 10,260, 99,900, 1,000,080 cases. --resume keeps the stages already recorded
in WORK/results.json whose outputs are still there (a long run can be continued). Standard library only.
"""
import argparse
import filecmp
import json
import os
import resource
import subprocess
import sys
import time

SOURCE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DRAWS = {"1e3": 2, "1e4": 19, "1e5": 185, "1e6": 1852}
MERGE_LIMIT_S = 30.0       # the merge of 1,000 shards of a large run
RATE_TOLERANCE = 0.10      # cases/min/core "constant": within 10 % of the smallest size's figure


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed(args, env, log):
    """Runs one command under /usr/bin/time: wall s, CPU s, peak RSS MB."""
    stats = log + ".time"
    with open(log, "w") as out:
        r = subprocess.run(["/usr/bin/time", "-o", stats, "-f", "%e %U %S %M"] + args, env=env, stdout=out,
                           stderr=subprocess.STDOUT)
    if r.returncode != 0:
        sys.exit(f"{' '.join(args)}: exit {r.returncode} (see {log})")
    wall, user, sys_s, rss_kb = open(stats).read().split()[-4:]
    return {"wall_s": float(wall), "cpu_s": float(user) + float(sys_s), "peak_rss_mb": int(rss_kb) / 1024}


def write_config(work, size):
    config = json.load(open(os.path.join(SOURCE, "data/harness.json")))
    config["design"] = os.path.join(SOURCE, "data/paper.json")
    config["noise_draws"] = DRAWS[size]
    path = os.path.join(work, f"h{size}.json")
    with open(path, "w") as f:
        json.dump(config, f, indent=1)
    return path


def task_command(runner, config, shard_dir, n, i, env):
    """One task as the scheduler starts it: the Slurm array script with its environment, or the container command
    of the Kubernetes Indexed Job (scripts/cluster/harness-indexed-job.yaml) with JOB_COMPLETION_INDEX and SHARDS
    (= completions) set to i and n."""
    if runner == "slurm":
        return ["bash", os.path.join(SOURCE, "scripts/cluster/harness-array.sbatch")], dict(
            env, TOPOCAL_HARNESS_CONFIG=config, TOPOCAL_SHARD_DIR=shard_dir, SLURM_ARRAY_TASK_ID=str(i),
            SLURM_ARRAY_TASK_COUNT=str(n), SLURM_CPUS_PER_TASK="1")
    import yaml  # python3-yaml, as tests/cli/scale_out_test.py
    with open(os.path.join(SOURCE, "scripts/cluster/harness-indexed-job.yaml")) as f:
        container = yaml.safe_load(f)["spec"]["template"]["spec"]["containers"][0]
    task_env = dict(env, **{e["name"]: e["value"] for e in container["env"]})
    task_env.update(SHARDS=str(n), HARNESS_CONFIG=config, SHARD_DIR=shard_dir, JOB_COMPLETION_INDEX=str(i))
    return container["command"] + container["args"], task_env


def sharded(config, shard_dir, n, slots, env, tasks=None, runner="slurm"):
    """Each task (the first `tasks` of the n, or all) through the runner's file, `slots` tasks at a time (a
    scheduler's free slots); CPU of all tasks."""
    tasks = n if tasks is None else tasks
    cpu0, t0 = children_cpu(), time.monotonic()
    running, next_task = [], 0
    while next_task < tasks or running:
        while next_task < tasks and len(running) < slots:
            command, task_env = task_command(runner, config, shard_dir, n, next_task, env)
            running.append((next_task, subprocess.Popen(command, env=task_env, stdout=subprocess.DEVNULL,
                                                        stderr=subprocess.DEVNULL)))
            next_task += 1
        task, p = running.pop(0)
        if p.wait() != 0:
            sys.exit(f"array task {task}/{n}: exit {p.returncode}")
    files = [f for f in os.listdir(shard_dir) if f.startswith("shard-")]
    if len(files) != tasks:
        sys.exit(f"{shard_dir}: {len(files)} shard files, expected {n}")
    size = sum(os.path.getsize(os.path.join(shard_dir, f)) for f in files)
    return {"wall_s": time.monotonic() - t0, "cpu_s": children_cpu() - cpu0, "shard_bytes": size}


def merge(shard_dir, results, env, log):
    script = os.path.join(SOURCE, "scripts/cluster/harness-merge.sbatch")
    return timed(["bash", script], dict(env, TOPOCAL_SHARD_DIR=shard_dir, TOPOCAL_RESULTS=results), log)


def same_files(a, b):
    names = sorted(os.listdir(a))
    return names == sorted(os.listdir(b)) and all(filecmp.cmp(os.path.join(a, n), os.path.join(b, n), shallow=False)
                                                  for n in names)


def output_sizes(d):
    return {n: os.path.getsize(os.path.join(d, n)) for n in sorted(os.listdir(d))}


def cases_of(d):
    return json.load(open(os.path.join(d, "summary.json")))["cases"]["total"]


def measure(size, n, args, env, results):
    """Single run, sharded run, merge and cmp of one size; each stage kept in `results` as it completes."""
    key = f"{size}/{n}" + (f" {args.runner}" if args.runner != "slurm" else "")
    rec = results.setdefault(key, {})
    base = os.path.join(args.work, size)
    os.makedirs(base, exist_ok=True)
    config = write_config(args.work, size)
    suffix = f"-{args.runner}" if args.runner != "slurm" else ""
    single, shards, merged = (os.path.join(base, d) for d in ("single", f"shards-{n}{suffix}", f"merged-{n}{suffix}"))

    def stage(name, have, run):
        if not (args.resume and name in rec and have()):
            print(f"{key}: {name} ...", flush=True)
            rec[name] = run()
            json.dump(results, open(os.path.join(args.work, "results.json"), "w"), indent=1)

    if not args.skip_single:
        stage("single", lambda: os.path.exists(os.path.join(single, "summary.json")),
              lambda: timed([args.topocal, "harness", "--quiet", "--config", config, "--out", single, "--jobs", "1"],
                            env, os.path.join(base, "single.log")))
        rec["single"]["outputs"] = output_sizes(single)
    stage("shards", lambda: len(os.listdir(shards)) == n if os.path.isdir(shards) else False,
          lambda: sharded(config, shards, n, args.slots, env, runner=args.runner))
    stage("merge", lambda: os.path.exists(os.path.join(merged, "summary.json")),
          lambda: merge(shards, merged, env, os.path.join(base, f"merge-{n}.log")))
    rec["cases"] = cases_of(merged)
    rec["merge"]["outputs"] = output_sizes(merged)
    rec["identical"] = same_files(single, merged) if os.path.isdir(single) else None
    json.dump(results, open(os.path.join(args.work, "results.json"), "w"), indent=1)
    return rec


MASK = (1 << 64) - 1


def splitmix64(x):
    x = (x + 0x9E3779B97F4A7C15) & MASK
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & MASK
    return x ^ (x >> 31)


def sample(size, n, k, args, env, results):
    """The first k tasks of an n-task array of `size` cases: the sharded cases/min/core of a size whose full runs
    cost more than there is time for (each task enumerates every case and sets up as in the full run)."""
    key = f"{size}/{n} sample of {k}"
    shards = os.path.join(args.work, size + "-sample", f"shards-{n}")
    subprocess.run(["rm", "-rf", shards])
    os.makedirs(os.path.dirname(shards), exist_ok=True)
    print(f"{key} ...", flush=True)
    rec = sharded(write_config(args.work, size), shards, n, args.slots, env, tasks=k)
    total = DRAWS[size] * 540
    rec["sample_cases"] = sum(len(range(i, total, n)) for i in range(k))
    results[key] = {"cases": total, "sample": rec}
    json.dump(results, open(os.path.join(args.work, "results.json"), "w"), indent=1)
    print(f"{key}: {rec['sample_cases']} cases, {rec['cpu_s']:.1f} s CPU: "
          f"{rate(rec['sample_cases'], rec['cpu_s']):.0f} cases/min/core")


def constructed_merge(size, n, args, env, results):
    """The merge of n shard files of `size` cases without computing them: one real shard (500 cases) gives the header
    and the case results, which every constructed shard repeats under its own indices and seeds (the merge checks
    both, as for computed shards). Measures the merge only; there is no single run to compare with."""
    key = f"{size}/{n} constructed"
    base = os.path.join(args.work, size + "-constructed")
    shards, merged = os.path.join(base, f"shards-{n}"), os.path.join(base, f"merged-{n}")
    os.makedirs(shards, exist_ok=True)
    config = write_config(args.work, size)
    print(f"{key}: one real shard, then {n} constructed ...", flush=True)
    real_dir = os.path.join(base, "real")
    subprocess.run([args.topocal, "harness", "--quiet", "--config", config, "--out", real_dir, "--shard",
                    f"0/{DRAWS[size] * 540 // 500}"], env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    real = json.load(open(os.path.join(real_dir, os.listdir(real_dir)[0])))
    rows, total = real.pop("cases"), real["total_cases"]
    config_seed = splitmix64(real["config"]["seed"])
    for i in range(n):
        real["shard"] = {"index": i, "count": n}
        head = json.dumps(real, indent=1)[:-2]
        lines = []
        for index in range(i, total, n):
            row = rows[index % len(rows)]
            lines.append(json.dumps([index, splitmix64(config_seed ^ index)] + row[2:], separators=(",", ":")))
        with open(os.path.join(shards, f"shard-{i}-of-{n}.json"), "w") as f:
            f.write(head + ',\n "cases": [\n  ' + ",\n  ".join(lines) + "\n ]\n}\n")
    rec = {"cases": total, "constructed": True}
    rec["shards"] = {"shard_bytes": sum(os.path.getsize(os.path.join(shards, f)) for f in os.listdir(shards)),
                     "cpu_s": float("nan")}
    subprocess.run(["rm", "-rf", merged])
    rec["merge"] = merge(shards, merged, env, os.path.join(base, f"merge-{n}.log"))
    rec["merge"]["outputs"] = output_sizes(merged)
    rec["identical"] = None
    results[key] = rec
    json.dump(results, open(os.path.join(args.work, "results.json"), "w"), indent=1)


def rate(cases, cpu_s):
    return cases / (cpu_s / 60) if cpu_s > 0 else float("nan")


def report(results):
    rows = sorted(results.items(), key=lambda kv: (kv[1].get("cases", 0), int(kv[0].split("/")[1].split()[0]), kv[0]))
    first_rate = None
    print(f"\n{'cases':>9} {'shards':>6} | {'single c/min/core':>17} {'sharded c/min/core':>18} {'vs first':>8} | "
          f"{'merge wall s':>12} {'CPU s':>6} {'RSS MB':>7} | {'single RSS':>10} | {'shards MB':>9} "
          f"{'csv MB':>7} {'svg KB':>6} | identical")
    for key, r in rows:
        if "sample" in r:
            sm = r["sample"]
            print(f"{r['cases']:>9} {key.split('/')[1].split()[0]:>6} | {'':>17} {rate(sm['sample_cases'], sm['cpu_s']):>18.0f}"
                  f" {'':>8} | first {key.split()[-1]} tasks only ({sm['sample_cases']} cases): no merge")
            continue
        if "merge" not in r:
            continue
        cases, n = r["cases"], int(key.split("/")[1].split()[0])
        s_rate = rate(cases, r["single"]["cpu_s"]) if "single" in r else float("nan")
        m_rate = rate(cases, r["shards"]["cpu_s"])
        if s_rate == s_rate:  # the ratio compares single runs: an array's rate depends on its cases per task
            first_rate = first_rate or s_rate
        ratio = s_rate / first_rate if first_rate and s_rate == s_rate else float("nan")
        outs = r["merge"]["outputs"]
        svg = max(v for k, v in outs.items() if k.endswith(".svg")) / 1024
        limit = f" (<= {MERGE_LIMIT_S:.0f})" if n >= 1000 else ""
        ok_merge = "" if n < 1000 or r["merge"]["wall_s"] <= MERGE_LIMIT_S else " OVER"
        print(f"{cases:>9} {n:>6} | {s_rate:>17.0f} {m_rate:>18.0f} {ratio:>8.2f} | "
              f"{r['merge']['wall_s']:>7.2f}{limit}{ok_merge:<5} {r['merge']['cpu_s']:>6.2f} "
              f"{r['merge']['peak_rss_mb']:>7.0f} | {r['single']['peak_rss_mb'] if 'single' in r else float('nan'):>10.0f}"
              f" | {r['shards']['shard_bytes'] / 2**20:>9.1f} {outs['cases.csv'] / 2**20:>7.1f} {svg:>6.0f} | "
              f"{ {True: 'yes', False: 'NO', None: '-'}[r['identical']] }"
              f"{' (constructed shards: merge only)' if r.get('constructed') else ''}"
              f"{' (Kubernetes Indexed Job command)' if key.endswith('k8s') else ''}")
    print(f"limits: cases/min/core constant (within {RATE_TOLERANCE:.0%} of the first row: 'vs first' in "
          f"[{1 - RATE_TOLERANCE:.2f}, {1 + RATE_TOLERANCE:.2f}]); merge of 1,000 shards <= {MERGE_LIMIT_S:.0f} s; "
          "merged files byte-identical to the single run; plots of bounded size (<= ~250 KB)")
    print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())} on {os.cpu_count()} cores")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--topocal", default=os.path.join(SOURCE, "build/tools/topocal"))
    ap.add_argument("--work", default="/tmp/harness-scale-bench")
    ap.add_argument("--sizes", default="1e3,1e4,1e5", help="comma-separated, of " + ", ".join(DRAWS))
    ap.add_argument("--shards", type=int, default=100)
    ap.add_argument("--slots", type=int, default=2, help="array tasks running at once (default 2)")
    ap.add_argument("--runner", choices=("slurm", "k8s"), default="slurm",
                    help="the tasks through the Slurm array script or the Kubernetes Indexed Job's command")
    ap.add_argument("--merge-1000", action="store_true", help="also split the largest size into 1,000 shards")
    ap.add_argument("--skip-single", action="store_true", help="no single run (cases/min/core from the shards)")
    ap.add_argument("--constructed-merge", metavar="SIZE", help="time the merge of --shards constructed shard "
                    "files of SIZE cases (e.g. 1e6 with --shards 1000) without computing the cases")
    ap.add_argument("--sample", metavar="SIZE:K", help="run only the first K tasks of a --shards array of SIZE "
                    "cases (e.g. 1e6:10): cases/min/core of a size too large to run whole")
    ap.add_argument("--resume", action="store_true")
    ap.add_argument("--report-only", action="store_true")
    args = ap.parse_args()
    args.topocal = os.path.abspath(args.topocal)
    os.makedirs(args.work, exist_ok=True)
    path = os.path.join(args.work, "results.json")
    results = json.load(open(path)) if os.path.exists(path) else {}
    env = dict(os.environ, PATH=os.path.dirname(args.topocal) + os.pathsep + os.environ["PATH"])
    if args.sample:
        size, k = args.sample.split(":")
        sample(size, args.shards, int(k), args, env, results)
    elif args.constructed_merge:
        constructed_merge(args.constructed_merge, args.shards, args, env, results)
    elif not args.report_only:
        sizes = args.sizes.split(",")
        for size in sizes:
            measure(size, args.shards, args, env, results)
        if args.merge_1000:
            args.skip_single = True  # the single run of that size is already there
            measure(sizes[-1], 1000, args, env, results)
    report(results)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Scaling out as docs/scale-out.md shows it: scripts/cluster/harness-array.sbatch run as a Slurm array would run
it (SLURM_ARRAY_TASK_ID / SLURM_ARRAY_TASK_COUNT), and the container command of
scripts/cluster/harness-indexed-job.yaml run as Kubernetes runs an Indexed Job (JOB_COMPLETION_INDEX): each shard an
independent process, started together; the merged files must equal the unsharded run's byte for byte, for any
number of shards. calibrate-batch --shard splits the units so that the shards together calibrate each unit once.

usage: scale_out_test.py TOPOCAL_EXE SOURCE_DIR WORK_DIR
"""
import json
import os
import shutil
import subprocess
import sys

import yaml

TOPOCAL, SOURCE, WORK = os.path.abspath(sys.argv[1]), sys.argv[2], sys.argv[3]
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAIL:", what, file=sys.stderr)


shutil.rmtree(WORK, ignore_errors=True)
os.makedirs(WORK)
env = dict(os.environ, PATH=os.path.dirname(os.path.abspath(TOPOCAL)) + os.pathsep + os.environ["PATH"])

# A small sweep: 2 sigmas x 3 calibration errors x 1 noise level = 6 cases (~0.1 s), as tests/cli/harness_cli_test.
with open(os.path.join(WORK, "h.json"), "w") as f:
    json.dump({"design": os.path.join(SOURCE, "data/paper.json"), "seed": 3,
               "distortion": {"seidel_sigma_per_mm2": [-1e-6, 6.3e-5]}, "noise_px": [0.01], "noise_draws": 1,
               "calibration_errors": [-1, 0, 0.1], "limits": {"dk": 0.05, "dP_D": 0.25}}, f)


def run(args, extra_env=None, expect=0):
    r = subprocess.run(args, cwd=WORK, env=dict(env, **(extra_env or {})), capture_output=True, text=True)
    check(r.returncode == expect, f"{' '.join(args)}: exit {r.returncode}, expected {expect}: {r.stderr}")
    return r


def together(commands):
    """Starts every (args, env) at once, as a scheduler does, and waits for all."""
    procs = [subprocess.Popen(a, cwd=WORK, env=dict(env, **e), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for a, e in commands]
    for (a, _), p in zip(commands, procs):
        out, err = p.communicate()
        check(p.returncode == 0, f"{' '.join(a)}: exit {p.returncode}: {err}")


def same_tree(a, b, what):
    names_a = sorted(os.listdir(os.path.join(WORK, a)))
    names_b = sorted(os.listdir(os.path.join(WORK, b)))
    check(names_a == names_b, f"{what}: files {names_a} != {names_b}")
    for name in names_a:
        with open(os.path.join(WORK, a, name), "rb") as fa, open(os.path.join(WORK, b, name), "rb") as fb:
            check(fa.read() == fb.read(), f"{what}: {name} differs from the unsharded run")


run(["topocal", "harness", "--config", "h.json", "--out", "single/"])

# ---- Slurm job array: the sbatch files as they are, N = 3 and N = 4 ----------------------------------------------
array = os.path.join(SOURCE, "scripts/cluster/harness-array.sbatch")
merge = os.path.join(SOURCE, "scripts/cluster/harness-merge.sbatch")
for n in (3, 4):
    shard_dir, results = f"slurm-shards-{n}", f"slurm-results-{n}"
    common = {"TOPOCAL_HARNESS_CONFIG": "h.json", "TOPOCAL_SHARD_DIR": shard_dir, "SLURM_ARRAY_TASK_COUNT": str(n),
              "SLURM_CPUS_PER_TASK": "1"}
    together([(["bash", array], dict(common, SLURM_ARRAY_TASK_ID=str(i))) for i in range(n)])
    check(len(os.listdir(os.path.join(WORK, shard_dir))) == n, f"slurm: {n} shard files")
    run(["bash", merge], {"TOPOCAL_SHARD_DIR": shard_dir, "TOPOCAL_RESULTS": results})
    same_tree(results, "single", f"slurm array of {n}")

# ---- Kubernetes Indexed Job: the container command of the manifest with each JOB_COMPLETION_INDEX ----------------
with open(os.path.join(SOURCE, "scripts/cluster/harness-indexed-job.yaml")) as f:
    job = yaml.safe_load(f)
spec = job["spec"]
check(spec["completionMode"] == "Indexed", "k8s: completionMode Indexed")
container = spec["template"]["spec"]["containers"][0]
container_env = {e["name"]: e["value"] for e in container["env"]}
check(int(container_env["SHARDS"]) == spec["completions"], "k8s: SHARDS equals completions")
container_env.update({"HARNESS_CONFIG": "h.json", "SHARD_DIR": "k8s-shards"})  # the volume's paths, here
together([(container["command"] + container["args"], dict(container_env, JOB_COMPLETION_INDEX=str(i)))
          for i in range(spec["completions"])])
run(["topocal", "harness", "merge", "--out", "k8s-results/", "k8s-shards/"])
same_tree("k8s-results", "single", "kubernetes indexed job")

# ---- calibrate-batch --shard: every unit in exactly one shard --------------------------------------------------
# Units whose inputs are refused at once (no images) keep this cheap: each shard lists exactly its own units.
for serial in ("A1", "B2", "C3", "D4", "E5"):
    os.makedirs(os.path.join(WORK, "inputs", serial))
    with open(os.path.join(WORK, "inputs", serial, "unit-inputs.json"), "w") as f:
        f.write("{ not json")
seen = []
for i in range(2):
    r = run(["topocal", "unit", "calibrate-batch", "inputs/", "--out", "units/", "--quiet", "--shard", f"{i}/2"],
            expect=2)  # bad input only: exit 2 (docs/robustness.md)
    seen += [s for s in ("A1", "B2", "C3", "D4", "E5") if f"inputs/{s}/unit-inputs.json" in r.stdout]
check(sorted(seen) == ["A1", "B2", "C3", "D4", "E5"], f"batch shards cover every unit once: {seen}")
check(not os.path.exists(os.path.join(WORK, "units")), "failed batch shards leave no units/ folder")
r = run(["topocal", "unit", "calibrate-batch", "inputs/", "--out", "units/", "--shard", "2/2"], expect=2)
check("--shard" in r.stderr, f"bad --shard named: {r.stderr}")

if failures:
    print(f"{len(failures)} check(s) failed", file=sys.stderr)
    sys.exit(1)
shutil.rmtree(WORK, ignore_errors=True)
print("scale-out checks passed")

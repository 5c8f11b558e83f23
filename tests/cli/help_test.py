#!/usr/bin/env python3
"""Every verb's --help (and every sub-verb's) shows one example and the defaults; lists take one syntax.

usage: help_test.py TOPOCAL_EXE
"""
import re
import subprocess
import sys

TOPOCAL = sys.argv[1]
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAIL:", what, file=sys.stderr)


def help_of(*verb):
    r = subprocess.run([TOPOCAL, *verb, "--help"], capture_output=True, text=True)
    check(r.returncode == 0, f"{' '.join(verb)} --help: exit {r.returncode}")
    return r.stdout


def subcommands(text):
    if "Subcommands:" not in text:
        return []
    block = text.split("Subcommands:", 1)[1].split("\n\n", 1)[0]  # up to the footer
    return [m.group(1) for m in re.finditer(r"^  (\S+)\s", block, re.M)]


verbs = [(v,) for v in subcommands(help_of())]
check(len(verbs) >= 17, f"verbs found: {verbs}")
for verb in list(verbs):
    verbs += [verb + (s,) for s in subcommands(help_of(*verb))]
for verb in verbs:
    text = help_of(*verb)
    example = re.search(r"Example:\n  (topocal .*)", text)
    check(example is not None, f"{' '.join(verb)}: no example")
    if example and len(verb) == 1 and verb[0] not in ("unit", "device", "fleet"):
        check(example.group(1).startswith("topocal " + " ".join(verb)), f"{' '.join(verb)}: example of another verb")

# Defaults are shown, including the new --jobs default (the cores available, a number).
# CLI11 shows a default as TYPE=VALUE.
check(re.search(r"--jobs INT(:[^=\n]*)?=\d+", help_of("harness")) is not None, "harness --jobs shows its default")
check(re.search(r"--jobs INT:.*=\d+", help_of("unit", "calibrate-batch")) is not None,
      "calibrate-batch --jobs shows its default")
check("--model TEXT=brown5" in help_of("calibrate"), "calibrate --model shows brown5")
check("=[]" not in help_of("unit", "calibrate"), "an empty list shows no default")
check("Example:" in help_of(), "topocal --help has an example")
# Defaults read as a user types them: no NaN sentinel, no value outside the option's own range, one example each.
for verb in verbs:
    text = help_of(*verb)
    check("=nan" not in text, f"{' '.join(verb)}: a default shown as nan")
    for low, high, value in re.findall(r"in \[(-?[\d.e+-]+) - (-?[\d.e+-]+)\]=(-?[\d.e+-]+)", text):
        check(float(low) <= float(value) <= float(high), f"{' '.join(verb)}: default {value} outside [{low}, {high}]")
    check(text.count("Example:") == 1, f"{' '.join(verb)}: {text.count('Example:')} examples")

# One syntax for lists: spaces or commas, both for calibrate --fix and unit --fix (the trap).
# The runs stop at a missing file, after parsing: the list itself is not what they refuse.
for verb in (("calibrate", "--model", "brown5"), ("unit", "calibrate", "--serial", "X")):
    r = subprocess.run([TOPOCAL, *verb, "--fix", "k3,p1", "p2", "--target", "missing-target.yaml", "--images",
                        "x.png", "--out", "cal-out.yaml"], capture_output=True, text=True)
    check(r.returncode == 2 and "--fix" not in r.stderr and "fix" not in r.stderr,
          f"{' '.join(verb[:2])} --fix k3,p1 p2: {r.returncode} {r.stderr}")

if failures:
    print(f"{len(failures)} check(s) failed", file=sys.stderr)
    sys.exit(1)
print(f"{len(verbs)} verbs: example and defaults shown")

#!/usr/bin/env python3
"""Every option and flag of every `topocal` verb (and sub-verb) is used by some test under tests/.

The options come from each verb's --help (CLI11's listing, so a new option is seen without editing this file); a
(verb, option) pair counts as tested when one test source under tests/ names both the verb and the option, e.g. a
C++ test running "reconstruct --image ... --calibration ..." or a Python test passing ["sweep", "--maps", ...].
This is a floor, not proof: the test that names the option must also assert its effect.

usage: option_coverage_test.py TOPOCAL_EXE TESTS_DIR [--list]
  --list   print every (verb, option) pair and whether a test uses it
"""
import pathlib
import re
import subprocess
import sys

TOPOCAL, TESTS_DIR = sys.argv[1], pathlib.Path(sys.argv[2])
LIST = "--list" in sys.argv[3:]
SELF = pathlib.Path(__file__).resolve()

# Options every verb has and that are not a feature of the verb.
COMMON = {"--help"}


def help_of(*verb):
    r = subprocess.run([TOPOCAL, *verb, "--help"], capture_output=True, text=True, timeout=30)
    if r.returncode != 0:
        sys.exit(f"FAIL: topocal {' '.join(verb)} --help exited {r.returncode}: {r.stderr.strip()}")
    return r.stdout


def subcommands(text):
    if "Subcommands:" not in text:
        return []
    block = text.split("Subcommands:", 1)[1].split("\n\n", 1)[0]
    return [m.group(1) for m in re.finditer(r"^  (\S+)\s", block, re.M)]


def options(text):
    """The long options of one --help page: CLI11 lists each as '  -s,--name TYPE ...' under 'Options:'."""
    found = []
    for m in re.finditer(r"^\s+(?:-\w,)?(--[A-Za-z0-9][\w-]*)", text, re.M):
        if m.group(1) not in COMMON and m.group(1) not in found:
            found.append(m.group(1))
    return found


verbs = [(v,) for v in subcommands(help_of())]
if len(verbs) < 17:
    sys.exit(f"FAIL: only {len(verbs)} verbs found in topocal --help: {verbs}")
for verb in list(verbs):
    verbs += [verb + (s,) for s in subcommands(help_of(*verb))]

sources = {}
for path in sorted(TESTS_DIR.rglob("*")):
    if path.is_file() and path.suffix in (".cc", ".h", ".py", ".sh") and path.resolve() != SELF:
        sources[path] = path.read_text(errors="replace")


def names_verb(text, verb):
    if not verb:
        return True
    # The verb as a word of a command: "verb ", "verb", 'verb', or verb at the start of a quoted command line.
    word = re.escape(verb[-1])
    return re.search(r"(?<![\w-])" + word + r"(?![\w-])", text) is not None


def names_option(text, option):
    return re.search(re.escape(option) + r"(?![\w-])", text) is not None


pairs, missing = 0, []
for verb in [()] + verbs:  # () is topocal's own options (--version, --quiet), before any verb
    for option in options(help_of(*verb).split("Subcommands:", 1)[0]):
        pairs += 1
        users = [p for p, text in sources.items() if names_verb(text, verb) and names_option(text, option)]
        if LIST:
            print(f"{' '.join(verb):24} {option:28} {', '.join(str(p.relative_to(TESTS_DIR)) for p in users[:3])}")
        if not users:
            missing.append(" ".join(("topocal",) + verb + (option,)))

if missing:
    print(f"{len(missing)} of {pairs} options are used by no test under {TESTS_DIR}:", file=sys.stderr)
    for m in missing:
        print("  " + m, file=sys.stderr)
    sys.exit(1)
print(f"{len(verbs)} verbs, {pairs} options: each used by a test")

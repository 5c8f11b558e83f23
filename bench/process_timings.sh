#!/usr/bin/env bash
# Whole-process timings: wall time, CPU time and peak RSS of `/bin/true` (the peer: what any process costs
# here), `topocal --version`, `--help`, `sweep` of the paper, `unit calibrate` of the demo unit (SN-DEMO-0001 of
# scripts/demo-unit.sh: 4000 x 3000 target and reference sphere; its uncertainty by linear propagation, the default,
# and by 200 Monte Carlo draws, the cross-check; the peer, OpenCV's calibration of the same target view by
# bench/opencv_unit_peer.py) and the README's harness runs
# (data/harness.json on one thread and on every core, data/harness-assembly.json), each the median of N runs by
# /usr/bin/time -v: wall time (nanosecond clock), CPU time (user + system, in 10 ms steps; the figure that holds when
# other processes share the cores) and peak RSS. Given a second binary (BEFORE, e.g. main's build), the two run interleaved — before, after, before,
# ... — so that both see the same machine, and the table has both. Prints a markdown table and the machine's load,
# which the wall times depend on (2 cores shared: run it on a quiet machine).
# Usage: bash bench/process_timings.sh [N] [TOPOCAL] [BEFORE]   (defaults: 5, build/tools/topocal, none)
set -euo pipefail
cd "$(dirname "$0")/.."
n=${1:-5}
topocal=$(realpath "${2:-build/tools/topocal}")
before=${3:+$(realpath "$3")}
export TOPOCAL_DATA_DIR=${TOPOCAL_DATA_DIR:-$PWD/data}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The demo unit's inputs, rendered once (as scripts/demo-unit.sh renders them) and kept in build/.
demo=build/demo-unit/line/SN-DEMO-0001
if [ ! -f "$demo/target.png" ] || [ ! -f "$demo/sphere.png" ]; then
  mkdir -p "$demo"
  "$topocal" render-target --target data/target-topographer.yaml --out "$demo/target.png" --width 4000 --height 3000 \
    --focal-mm 5.2 --pixel-pitch-um 1.12 --sigma 6.3e-5 --distance-mm 70 --supersampling 4 --noise 1 >/dev/null
  "$topocal" render-spots --config data/paper.json --device data/device.json --sigma 6.3e-5 \
    --sphere-radius-mm 7.8 --out "$demo/sphere.png" >/dev/null
fi

# One run of "$@" under /usr/bin/time: appends wall s, CPU s and peak RSS MB to the files $1.wall, $1.cpu, $1.rss.
run_once() {
  local tag=$1
  shift
  rm -rf "$work/out"
  # Wall time by the nanosecond clock (/usr/bin/time's is in 10 ms steps); it includes /usr/bin/time's own ~1 ms,
  # which the /bin/true row shows.
  local t0 t1
  t0=$(date +%s%N)
  /usr/bin/time -v -o "$work/time" "$@" >/dev/null 2>&1
  t1=$(date +%s%N)
  echo "($t1 - $t0) / 1000000000" | bc -l >> "$work/$tag.wall"
  awk -F': ' '/User time|System time/ {s += $2} END {print s}' "$work/time" >> "$work/$tag.cpu"
  awk -F': ' '/Maximum resident set size/ {print $2 / 1024}' "$work/time" >> "$work/$tag.rss"
}
median() { sort -g "$1" | awk -v f="$2" '{a[NR] = $1} END {printf f, a[int((NR + 1) / 2)]}'; }
cell() { echo "$(median "$work/$1.wall" %.3f) / $(median "$work/$1.cpu" %.2f) / $(median "$work/$1.rss" %.0f)"; }

# A figure: N runs of the command line (its first word "topocal" stands for the binary), interleaved with BEFORE's.
figure() {
  local label=$1
  shift
  rm -f "$work"/a.* "$work"/b.*
  for _ in $(seq "$n"); do
    if [ -n "$before" ]; then run_once b "${@/#topocal/$before}"; fi
    run_once a "${@/#topocal/$topocal}"
  done
  if [ -n "$before" ]; then echo "| $label | $(cell b) | $(cell a) |"; else echo "| $label | $(cell a) |"; fi
}

echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)   runs per figure: $n   binary: $topocal${before:+   before: $before}"
echo
if [ -n "$before" ]; then
  echo "| process | before: wall s / CPU s / peak RSS MB (medians) | after |"
  echo "|---|---:|---:|"
else
  echo "| process | wall s / CPU s / peak RSS MB (medians) |"
  echo "|---|---:|"
fi
figure "/bin/true (peer)" /bin/true
figure "topocal --version" topocal --version
figure "topocal --help" topocal --help
figure "topocal sweep --config data/paper.json" topocal sweep --config data/paper.json
figure "topocal unit calibrate (demo unit)" topocal unit calibrate --serial SN-DEMO-0001 \
  --target data/target-topographer.yaml --images "$demo/target.png" --reference-sphere "$demo/sphere.png" \
  --sphere-radius-mm 7.8 --out "$work/out/SN-DEMO-0001"
# The peer: OpenCV's calibration of the same target view alone (bench/opencv_unit_peer.py), in its own process.
figure "OpenCV calibration of the unit's target view (peer)" /usr/bin/python3 bench/opencv_unit_peer.py \
  "$demo/target.png"
figure "topocal unit calibrate (demo unit, 200 Monte Carlo draws)" topocal unit calibrate --serial SN-DEMO-0001 \
  --target data/target-topographer.yaml --images "$demo/target.png" --reference-sphere "$demo/sphere.png" \
  --sphere-radius-mm 7.8 --uncertainty 200 --out "$work/out/SN-DEMO-0001"
# The README's harness runs: the residual-distortion sweep on one thread and on every core, the assembly sweep.
figure "topocal harness --config data/harness.json --jobs 1" topocal harness --config data/harness.json \
  --out "$work/out" --jobs 1 --quiet
figure "topocal harness --config data/harness.json (every core)" topocal harness --config data/harness.json \
  --out "$work/out" --quiet
figure "topocal harness --config data/harness-assembly.json" topocal harness --config data/harness-assembly.json \
  --out "$work/out" --quiet
echo
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"

#!/usr/bin/env bash
# Whole-process timings (issue 15): wall time, CPU time and peak RSS of `topocal --help`, `topocal sweep` of the paper and
# `topocal unit calibrate` of the demo unit (SN-DEMO-0001 of scripts/demo-unit.sh: 4000 x 3000 target and reference
# sphere, 200 uncertainty draws), each the median of N runs by /usr/bin/time -v: wall time, CPU time (user + system,
# the figure that holds when other processes share the cores) and peak RSS. Prints a markdown table and the
# machine's load, which the wall times depend on (2 cores shared: run it on a quiet machine).
# Usage: bash bench/process_timings.sh [N] [TOPOCAL]   (defaults: 5, build/tools/topocal)
set -euo pipefail
cd "$(dirname "$0")/.."
n=${1:-5}
topocal=$(realpath "${2:-build/tools/topocal}")
export TOPOCAL_DATA_DIR=${TOPOCAL_DATA_DIR:-$PWD/data}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The demo unit's inputs, rendered once (as scripts/demo-unit.sh renders them) and kept in build/.
demo=build/demo-unit/line/SN-DEMO-0001
if [ ! -f "$demo/target.png" ] || [ ! -f "$demo/sphere.png" ]; then
  mkdir -p "$demo"
  "$topocal" render-target --target data/target-topographer.yaml --out "$demo/target.png" --width 4000 --height 3000 \
    --focal-mm 5.2 --pixel-pitch-um 1.12 --sigma 6.3e-5 --distance-mm 70 --supersampling 4 --noise 1 >/dev/null
  "$topocal" render-spots --config data/paper.json --camera data/camera.json --sigma 6.3e-5 \
    --sphere-radius-mm 7.8 --out "$demo/sphere.png" >/dev/null
fi

# median wall seconds, median CPU seconds and median peak RSS (MB) of N runs of "$@"
measure() {
  local walls=() cpus=() rss=()
  for _ in $(seq "$n"); do
    rm -rf "$work/out"
    /usr/bin/time -v -o "$work/time" "$@" >/dev/null 2>&1
    walls+=("$(awk -F': ' '/Elapsed \(wall clock\)/ {split($2, t, ":"); print t[1] * 60 + t[2]}' "$work/time")")
    cpus+=("$(awk -F': ' '/User time|System time/ {s += $2} END {print s}' "$work/time")")
    rss+=("$(awk -F': ' '/Maximum resident set size/ {print $2 / 1024}' "$work/time")")
  done
  printf '%s\n' "${walls[@]}" | sort -g | awk '{a[NR] = $1} END {printf "%.3f ", a[int((NR + 1) / 2)]}'
  printf '%s\n' "${cpus[@]}" | sort -g | awk '{a[NR] = $1} END {printf "%.2f ", a[int((NR + 1) / 2)]}'
  printf '%s\n' "${rss[@]}" | sort -g | awk '{a[NR] = $1} END {printf "%.0f\n", a[int((NR + 1) / 2)]}'
}

echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)   runs per figure: $n   binary: $topocal"
echo
echo "| process | wall s (median) | CPU s (median) | peak RSS MB |"
echo "|---|---:|---:|---:|"
read -r w c m < <(measure "$topocal" --help)
echo "| topocal --help | $w | $c | $m |"
read -r w c m < <(measure "$topocal" sweep --config data/paper.json)
echo "| topocal sweep --config data/paper.json | $w | $c | $m |"
read -r w c m < <(measure "$topocal" unit calibrate --serial SN-DEMO-0001 --target data/target-topographer.yaml \
  --images "$demo/target.png" --reference-sphere "$demo/sphere.png" --sphere-radius-mm 7.8 --out "$work/out")
echo "| topocal unit calibrate (demo unit, 200 draws) | $w | $c | $m |"
echo
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"

#!/usr/bin/env bash
# The fleet at scale (docs/fleet.md "At scale"): for each size N (default 10^3, 10^4, 10^5 units), a generated line
# (build/bench/fleet_generate: four stations over three years, one drifting, 0.5 % FAIL; written once under WORK and
# reused) is ingested by `topocal fleet ingest` into a new database, station by station in calls of BATCH records
# (the records read and verified from their files, as always), checked by `fleet check`, and reported by `fleet
# report` REPEATS times. Each figure by /usr/bin/time -v: ingest records/s (wall and CPU: user + system), the
# report's wall and CPU time (median) and peak RSS, each printed beside its limit. Prints a markdown table, the
# date and the machine's load (2 cores shared: the CPU times hold when others build; the wall times do not).
# Usage: bash bench/fleet_scale.sh [SIZES] [REPEATS] [TOPOCAL] [GENERATOR] [WORK] [BATCH]
#   defaults: "1000 10000 100000", 3, build/tools/topocal, build/bench/fleet_generate, /tmp/topocal-fleet-scale, 500
set -euo pipefail
cd "$(dirname "$0")/.."
sizes=${1:-"1000 10000 100000"}
repeats=${2:-3}
topocal=$(realpath "${3:-build/tools/topocal}")
generate=$(realpath "${4:-build/bench/fleet_generate}")
work=${5:-/tmp/topocal-fleet-scale}
batch=${6:-500}
mkdir -p "$work"
ingest_limit=200   # records/s, one core
report_limit=10    # s

# /usr/bin/time -v of "$@" into $work/time; sets wall_s, cpu_s, rss_mb.
timed() {
  local t0 t1
  t0=$(date +%s%N)
  /usr/bin/time -v -o "$work/time" "$@" >"$work/out" 2>&1 || { cat "$work/out" >&2; exit 1; }
  t1=$(date +%s%N)
  wall_s=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", (b - a) / 1e9 }')
  cpu_s=$(awk -F': ' '/User time/ { u = $2 } /System time/ { s = $2 } END { printf "%.2f", u + s }' "$work/time")
  rss_mb=$(awk -F': ' '/Maximum resident/ { printf "%.0f", $2 / 1024 }' "$work/time")
}

median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

# Every station's records, in calls of $batch (the records of one station sorted, so in time order).
ingest_all() {
  local records=$1 db=$2
  for station in "$records"/LINE-*; do
    find "$station" -mindepth 2 -maxdepth 2 -type d | sort |
      xargs -n "$batch" "$topocal" fleet ingest --quiet --db "$db" --station "$(basename "$station")" >/dev/null
  done
}
export -f ingest_all
export topocal batch

echo "date $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), batch $batch, report repeats $repeats"
echo
echo "| units | ingest records/s wall (CPU) | limit | check | report wall s | CPU s | limit | peak RSS MB (ingest call, report) | database MB |"
echo "|---|---|---|---|---|---|---|---|---|"
for n in $sizes; do
  records="$work/fleet-$n"
  [ -d "$records" ] || "$generate" --units "$n" --out "$records" >/dev/null
  db="$work/fleet-$n.sqlite"
  rm -f "$db"
  timed bash -c "ingest_all '$records' '$db'"
  rate_wall=$(awk -v n="$n" -v t="$wall_s" 'BEGIN { printf "%.0f", n / t }')
  rate_cpu=$(awk -v n="$n" -v t="$cpu_s" 'BEGIN { printf "%.0f", n / t }')
  ingest_rss=$rss_mb
  check=$("$topocal" fleet check --db "$db" | grep -c ': ok: ' || true)
  walls=() cpus=() rss=0
  for _ in $(seq "$repeats"); do
    timed "$topocal" fleet report --quiet --db "$db" --out "$work/fleet-$n.html"
    walls+=("$wall_s")
    cpus+=("$cpu_s")
    rss=$(( rss_mb > rss ? rss_mb : rss ))
  done
  wall=$(printf '%s\n' "${walls[@]}" | median)
  cpu=$(printf '%s\n' "${cpus[@]}" | median)
  ok_ingest=$(awk -v r="$rate_cpu" -v l="$ingest_limit" 'BEGIN { print (r >= l) ? "ok" : "NOT MET" }')
  ok_report=$(awk -v w="$wall" -v l="$report_limit" 'BEGIN { print (w <= l) ? "ok" : "NOT MET" }')
  size_mb=$(du -m "$db" | cut -f1)
  echo "| $n | $rate_wall ($rate_cpu) | >= $ingest_limit: $ok_ingest | $([ "$check" = 1 ] && echo ok || echo FAILED) |" \
       "$wall | $cpu | <= $report_limit: $ok_report | $ingest_rss, $rss | $size_mb |"
done
echo
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"

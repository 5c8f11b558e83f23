#!/usr/bin/env bash
# The production-line workflow on two synthetic units, end to end (README "Per-unit calibration"):
#   render each unit's inputs (target image and reference-sphere image through its own camera distortion),
#   calibrate both with `topocal unit calibrate-batch`, and write a QA report per unit with `topocal report`.
# Usage: bash scripts/demo-unit.sh [OUT_DIR]   (default build/demo-unit; needs a built build/tools/topocal)
# Idempotent: inputs already rendered are reused.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-build/demo-unit}
topocal=${TOPOCAL:-build/tools/topocal}
[ -x "$topocal" ] || bash scripts/setup.sh build
mkdir -p "$out/line" "$out/reports"

# serial, camera sigma (mm^-2, paper Table IV levels)
units=("SN-DEMO-0001 6.3e-5" "SN-DEMO-0002 -6.3e-5")
for u in "${units[@]}"; do
  set -- $u
  serial=$1 sigma=$2 dir="$out/line/$1"
  mkdir -p "$dir"
  if [ ! -f "$dir/target.png" ]; then
    # Supersampling 4: the full 4000 x 3000 frame renders in ~20 s instead of ~40 s at the renderer's default.
    "$topocal" render-target --target data/target-topographer.yaml --out "$dir/target.png" --width 4000 --height 3000 \
      --focal-mm 5.2 --pixel-pitch-um 1.12 --sigma "$sigma" --distance-mm 70 --supersampling 4 --noise 1
  fi
  if [ ! -f "$dir/sphere.png" ]; then
    "$topocal" render-spots --config data/paper.json --device data/device.json --sigma "$sigma" \
      --sphere-radius-mm 7.8 --out "$dir/sphere.png"
  fi
  cat > "$dir/unit-inputs.json" <<JSON
{"serial": "$serial", "target": "$PWD/data/target-topographer.yaml", "images": "target.png",
 "reference_sphere": "sphere.png", "sphere_radius_mm": 7.8}
JSON
done

# --force: a rerun replaces the demo records and keeps the earlier ones in $out/units/.history/ (docs/unit-record.md)
"$topocal" unit calibrate-batch "$out/line" --out "$out/units" --force
for u in "${units[@]}"; do
  set -- $u
  "$topocal" report --unit "$out/units/$1" --out "$out/reports/$1.html"
done
echo "demo: records in $out/units/, reports in $out/reports/"

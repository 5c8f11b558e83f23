#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine (run as root):
#   bash scripts/setup.sh run    install what is missing, build, run the sweep on data/paper.json
#   bash scripts/setup.sh test   install what is missing, build, run the whole test suite (ctest)
# Idempotent: packages already installed are not touched; the build directory is reused.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:-run}
case "$mode" in run|test|build) ;; *) echo "usage: scripts/setup.sh run|test|build" >&2; exit 2 ;; esac

pkgs=(cmake g++ make pkg-config libopencv-dev libceres-dev libeigen3-dev libapriltag-dev libcli11-dev
      nlohmann-json3-dev libfmt-dev libssl-dev libsqlite3-dev zlib1g-dev libgtest-dev libgmock-dev libbenchmark-dev
      fonts-dejavu-core libopencv-contrib-dev liblapack-dev pybind11-dev python3-dev python3-numpy libdeflate-dev
      libpng-dev)
# fonts-dejavu-core: the maps' text (µm, mm², °) is drawn in DejaVu Sans through OpenCV's FreeType module.
# libopencv-contrib-dev: OpenCV aruco (Kalibr AprilGrids: calib/kalibr_grid_detector.cc).
# pybind11-dev, python3-dev, python3-numpy: the Python package (python/, docs/python.md).
# libdeflate-dev, libpng-dev: PNGs decoded in process (imageio/png_decode.cc).
# liblapack-dev: the spline fit's band Cholesky (topo/band_cholesky.h; Ceres' own dependencies bring it too).
# The real chessboard photographs the calibration tests compare against cv::calibrateCamera.
[ "$mode" = test ] && pkgs+=(opencv-doc)
# Headless Chromium renders the QA report to PDF/PNG in tests/report (the browser test fails without it); the
# report's font (DejaVu Sans, installed above) is named explicitly because --no-install-recommends leaves Chromium's
# fonts out.
[ "$mode" = test ] && pkgs+=(chromium)
# pdftotext reads the printed report's text back ("Page n of N" on every page).
[ "$mode" = test ] && pkgs+=(poppler-utils)
# The consumers' own libraries check topocal's exports and imports (tests/exchange): PyYAML reads ROS camera_info and
# Kalibr camchains, cv2 OpenCV calibration files, mrcal its .cameramodel.
[ "$mode" = test ] && pkgs+=(python3-yaml python3-opencv python3-mrcal)
# The Python package's tests (tests/python) run under pytest; docs/python.md's example draws with Matplotlib.
[ "$mode" = test ] && pkgs+=(python3-pytest python3-matplotlib)

missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

build=${TOPOCAL_BUILD_DIR:-build}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j"$(nproc)"

case "$mode" in
  run)  "$build/tools/topocal" sweep --config data/paper.json ;;
  test) ctest --test-dir "$build" --output-on-failure -j"$(nproc)" ;;
  build) ;;
esac

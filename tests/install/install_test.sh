#!/usr/bin/env bash
# Installs the build tree into a temporary prefix, builds and runs a consumer project against the installed CMake
# package and pkg-config file, and runs the installed CLI from another directory (its data found next to itself).
# Usage: install_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1
source=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix
cmake --install "$build" --prefix "$prefix" >/dev/null
test -f "$prefix/lib/cmake/topocal/topocalConfig.cmake"
test -f "$prefix/include/topocal/model/device.h"
test -f "$prefix/share/topocal/data/paper.json"
# The consumer, through find_package(topocal).
cmake -S "$source/tests/install/consumer" -B "$work/consumer" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/consumer" -j2 >/dev/null
out=$("$work/consumer/consumer")
echo "$out"
case "$out" in *"rx 8.3500 mm kx -0.4300"*) ;; *) echo "consumer: unexpected result" >&2; exit 1 ;; esac
# pkg-config sees the package.
test -f "$(PKG_CONFIG_PATH="$prefix/lib/pkgconfig" pkg-config --variable=includedir topocal)/topocal/model/device.h"
# The installed CLI, run from elsewhere, finds its data next to itself (no source or build path).
cd "$work"
"$prefix/bin/topocal" --version
mkdir unit && cd unit
"$prefix/bin/topocal" sweep --config "$prefix/share/topocal/data/paper.json" >/dev/null
# Images: the installed CLI writes a PNG and reads it back through its codec plugin (<prefix>/lib/topocal), loaded
# only by the verbs that touch an image.
data="$prefix/share/topocal/data"
"$prefix/bin/topocal" render-spots --config "$data/paper.json" --device "$data/device.json" --sigma 0 \
  --out spots.png >/dev/null
"$prefix/bin/topocal" detect --image spots.png --device "$data/device.json" --config "$data/paper.json" \
  --out detected.csv >/dev/null
test -s detected.csv
# Without the plugin: the image verbs fail with one line naming it, write nothing, and the others still run.
mv "$prefix/lib/topocal/libtopocal_imgcodecs.so" "$work/plugin.so"
set +e
msg=$("$prefix/bin/topocal" render-spots --config "$data/paper.json" --device "$data/device.json" --sigma 0 \
      --out missing.png 2>&1)
code=$?
set -e
case "$code:$msg" in 1:*"libtopocal_imgcodecs.so is not installed"*) ;; *) echo "without the plugin ($code): $msg" >&2; exit 1 ;; esac
test "$(wc -l <<< "$msg")" -eq 1
test ! -e missing.png
"$prefix/bin/topocal" sweep --config "$data/paper.json" >/dev/null
mv "$work/plugin.so" "$prefix/lib/topocal/libtopocal_imgcodecs.so"
# `unit calibrate` takes its default design and camera from the installed data: a run without images fails on the
# images, not on the data.
set +e
msg=$("$prefix/bin/topocal" unit calibrate --serial SN-1 --target "$prefix/share/topocal/data/target-topographer.yaml" \
      --images 'none*.png' --out "$work/unit/SN-1/" 2>&1)
set -e
case "$msg" in *"no file matches"*|*"none*.png"*) ;; *) echo "installed unit calibrate: $msg" >&2; exit 1 ;; esac
# topocal-sweep links no OpenCV (docs/startup.md): an object of the sweep's that pulled in an OpenCV caller of a
# library module would load OpenCV's 23 libraries for every sweep.
needed=$(readelf -d "$prefix/libexec/topocal-sweep")
if grep -i opencv <<< "$needed"; then echo "topocal-sweep links OpenCV" >&2; exit 1; fi
# topocal-detect links none of the libraries no capture needs (the drawing, database, digest and AprilTag ones, and
# OpenCV's calib3d, which only the calibration fits call).
needed=$(readelf -d "$prefix/libexec/topocal-detect")
if grep -E -i "freetype|sqlite|crypto|apriltag|aruco|calib3d" <<< "$needed"; then
  echo "topocal-detect links a library detection does not use" >&2
  exit 1
fi
# Without topocal-full: `--version` and the sweep still run (topocal-sweep), and so does `detect` (topocal-detect: a
# missing image is its own error); every other verb fails with one line naming the missing program, and writes
# nothing.
mv "$prefix/libexec/topocal-full" "$work/full"
"$prefix/bin/topocal" --version
"$prefix/bin/topocal" sweep --config "$data/paper.json" --json sweep.json >/dev/null
test -s sweep.json
set +e
msg=$("$prefix/bin/topocal" detect --image missing.png --config "$data/paper.json" --device "$data/device.json" \
      --out spots.csv 2>&1)
code=$?
set -e
case "$code:$msg" in
  2:*"missing.png: cannot be opened"*) ;;
  *) echo "detect without topocal-full ($code): $msg" >&2; exit 1 ;;
esac
test ! -e spots.csv
set +e
msg=$("$prefix/bin/topocal" simulate --config "$data/paper.json" --sigma 0 --out nofull.csv 2>&1)
code=$?
set -e
case "$code:$msg" in 1:*"cannot run"*"libexec/topocal-full"*) ;; *) echo "without topocal-full ($code): $msg" >&2; exit 1 ;; esac
test "$(wc -l <<< "$msg")" -eq 1
test ! -e nofull.csv
mv "$work/full" "$prefix/libexec/topocal-full"
# The Python package (when built): importable from the install prefix, from a directory outside the source and build
# trees, by Debian's interpreter; it reads the installed data.
if [ -f "$build/python/topocal/__init__.py" ]; then
  pydir=$(echo "$prefix"/lib/python3*/dist-packages)
  test -f "$pydir/topocal/__init__.py"
  test -f "$pydir/topocal/__init__.pyi"
  (cd "$work" && PYTHONPATH="$pydir" /usr/bin/python3 -c "
import topocal, sys
assert topocal.__file__.startswith('$pydir'), topocal.__file__
d = topocal.Device.load('$data/demo-unit-device.json')
c = topocal.Config.load('$data/paper.json')
print('installed python module', topocal.__version__, d.width_px, d.height_px)
")
fi
# The Debian package, with Debian 12's runtime dependencies.
(cd "$build" && cpack -G DEB -B "$work/deb" >/dev/null)
# (captured first: grep -q would close the pipe early and pipefail would report dpkg-deb's SIGPIPE)
info=$(dpkg-deb -I "$work"/deb/topocal_*_amd64.deb)
grep "Depends:.*libceres-dev" <<< "$info" >/dev/null
contents=$(dpkg-deb -c "$work"/deb/topocal_*_amd64.deb)
grep "usr/share/topocal/data/paper.json" <<< "$contents" >/dev/null
grep "usr/lib/topocal/libtopocal_imgcodecs.so" <<< "$contents" >/dev/null
grep "usr/libexec/topocal-full" <<< "$contents" >/dev/null
grep "usr/libexec/topocal-sweep" <<< "$contents" >/dev/null
grep "usr/libexec/topocal-detect" <<< "$contents" >/dev/null
if [ -f "$build/python/topocal/__init__.py" ]; then
  grep "usr/lib/python3.*/dist-packages/topocal/_topocal.*\.so" <<< "$contents" >/dev/null
  grep "usr/lib/python3.*/dist-packages/topocal/__init__.py" <<< "$contents" >/dev/null
  # ... and imports from the package's own files (extracted, as dpkg would place them under /usr).
  dpkg-deb -x "$work"/deb/topocal_*_amd64.deb "$work/deb-root"
  (cd "$work" && PYTHONPATH=$(echo "$work"/deb-root/usr/lib/python3*/dist-packages) /usr/bin/python3 -c \
    "import topocal; assert '/deb-root/usr/lib/' in topocal.__file__; print('.deb python module', topocal.__version__)")
fi
echo "install test passed"

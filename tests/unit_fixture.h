#pragma once
// Inputs of one topographer unit, rendered once per build tree and shared by the tests of `topocal unit` and
// `topocal report`: a region-of-interest camera (1120 x 1120 px of the paper's 1.12 um sensor, the geometry of
// pipeline/closed_loop.h at a tenth of the pixels), the 13 x 13 checkerboard of 0.9 mm squares at the cornea
// position, and a reference sphere, both through a camera with the paper's sigma = 6.3e-5 mm^-2.
// Requires TOPOCAL_EXE and TOPOCAL_BINARY_DIR (tests/CMakeLists.txt) and tests/cli_harness.h.
#include <fmt/format.h>
#include <unistd.h>

#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
#include <utility>

#include "tests/cli_harness.h"
#include "tests/device_file.h"
#include "util/io.h"

namespace topocal::testing_cli {

inline constexpr double kUnitSigmaPerMm2 = 6.3e-5;  // paper Table IV
inline constexpr double kUnitSphereRadiusMm = 7.8;  // a common reference ball (the paper's design radius re_mm)

// The directory with device.json (the nominal device of a 1120 x 1120 px sensor), target.yaml, view.png, sphere.png, blank.png (a grey frame: no target) and
// views/*.png (view.png and the target turned by 12 degrees about x and about y: a multi-view calibration).
// Built under a temporary name and renamed
// into place, so that tests running in parallel (ctest -j) never see a half-written set.
inline std::string UnitInputsDir() {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(TOPOCAL_BINARY_DIR) / "test-data" / "unit-inputs-v3";
  if (fs::exists(dir)) return dir.string();
  const fs::path tmp = dir.string() + fmt::format(".tmp-{}", ::getpid());
  fs::remove_all(tmp);
  fs::create_directories(tmp);
  util::WriteFileAtomic((tmp / "device.json").string(),
                        NominalDeviceText(R"({"pixel_pitch_um": 1.12, "width_px": 1120, "height_px": 1120,)"
                                          R"( "principal_point_px": [559.5, 559.5], "a_mm": 5.2})"));
  util::WriteFileAtomic((tmp / "target.yaml").string(),
                        "target_type: checkerboard\ntargetCols: 13\ntargetRows: 13\nrowSpacingMeters: 0.0009\n"
                        "colSpacingMeters: 0.0009\n");
  const auto t = tmp.string();
  const auto target = RunTopocal(fmt::format(
      "render-target --target {0}/target.yaml --out {0}/view.png --width 1120 --height 1120 --focal-mm 5.2 "
      "--pixel-pitch-um 1.12 --sigma {1} --distance-mm 70 --supersampling 8 --noise 1",
      t, kUnitSigmaPerMm2));
  if (target.exit_code != 0) throw std::runtime_error("rendering the unit's target failed: " + target.output);
  const auto sphere = RunTopocal(fmt::format(
      "render-spots --config {0}/data/paper.json --device {1}/device.json --sigma {2} --sphere-radius-mm {3} "
      "--out {1}/sphere.png",
      TOPOCAL_SOURCE_DIR, t, kUnitSigmaPerMm2, kUnitSphereRadiusMm));
  if (sphere.exit_code != 0) throw std::runtime_error("rendering the unit's reference sphere failed: " + sphere.output);
  fs::create_directories(tmp / "views");
  fs::copy_file(tmp / "view.png", tmp / "views" / "front.png");
  for (const auto& [file, tilt] : {std::pair{"x12", "--tilt-x-deg 12"}, std::pair{"y12", "--tilt-y-deg 12"},
                                  std::pair{"x-12", "--tilt-x-deg -12"}}) {
    const std::string name = fmt::format("{}/views/{}.png", t, file);
    const auto view = RunTopocal(fmt::format(
        "render-target --target {0}/target.yaml --out {1} --width 1120 --height 1120 --focal-mm 5.2 "
        "--pixel-pitch-um 1.12 --sigma {2} --distance-mm 70 {3} --supersampling 4 --noise 1",
        t, name, kUnitSigmaPerMm2, tilt));
    if (view.exit_code != 0) throw std::runtime_error("rendering a tilted view failed: " + view.output);
  }
  cv::imwrite((tmp / "blank.png").string(), cv::Mat(1120, 1120, CV_8U, cv::Scalar(110)));
  std::error_code ec;
  fs::rename(tmp, dir, ec);  // fails if another process got there first: theirs is as good
  if (ec) fs::remove_all(tmp);
  return dir.string();
}

}  // namespace topocal::testing_cli

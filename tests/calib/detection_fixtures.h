#pragma once
// Shared scenes for the detection tests: a 640 x 480 camera with moderate Brown-Conrady distortion, the targets,
// and the RMS of detected corners against the renderer's exact truth.
#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "calib/observations.h"
#include "calib/render_target.h"
#include "calib/target.h"
#include "model/camera_model.h"

namespace topocal::calib::testing {

inline model::CameraModel TestCamera() {
  model::CameraModel camera;
  camera.width_px = 640;
  camera.height_px = 480;
  camera.fx_px = 600.0;
  camera.fy_px = 602.0;
  camera.cx_px = 321.37;  // off-centre and off the pixel grid on purpose
  camera.cy_px = 238.81;
  camera.dist = {-0.18, 0.06, 4e-4, -3e-4, 0.0};  // barrel, ~3 px at the image corners
  return camera;
}

inline TargetDescription Checkerboard9x6() {
  return ParseTargetDescription(
      "target_type: checkerboard\ntargetCols: 9\ntargetRows: 6\nrowSpacingMeters: 0.02\ncolSpacingMeters: 0.02\n",
      "checkerboard-9x6");
}

// libapriltag's 1-cell-border tags (tagBorderBits: 1).
inline TargetDescription AprilGrid6x5() {
  return ParseTargetDescription(
      "target_type: aprilgrid\ntagCols: 6\ntagRows: 5\ntagSize: 0.03\ntagSpacing: 0.3\ntagBorderBits: 1\n",
      "aprilgrid-6x5");
}

// Kalibr's print (2-cell border, corner squares): a Kalibr YAML file unchanged.
inline TargetDescription KalibrGrid6x5() {
  return ParseTargetDescription(
      "target_type: aprilgrid\ntagCols: 6\ntagRows: 5\ntagSize: 0.03\ntagSpacing: 0.3\n", "kalibr-grid-6x5");
}

struct ErrorStats {
  double rms_px = 0;
  double max_px = 0;
  int matched = 0;
};

// Corner error against truth, matched by id; corners the detector reports without a truth entry count as misses.
inline ErrorStats CornerError(const ViewObservations& view, const std::vector<CornerTruth>& truth, int* unmatched) {
  std::map<int, Eigen::Vector2d> by_id;
  for (const auto& t : truth) by_id[t.id] = t.image_px;
  ErrorStats stats;
  double sum2 = 0;
  for (const auto& c : view.corners) {
    const auto it = by_id.find(c.id);
    if (it == by_id.end()) {
      if (unmatched) ++*unmatched;
      continue;
    }
    const double e = (c.image_px - it->second).norm();
    sum2 += e * e;
    stats.max_px = std::max(stats.max_px, e);
    ++stats.matched;
  }
  stats.rms_px = stats.matched ? std::sqrt(sum2 / stats.matched) : 0.0;
  return stats;
}

}  // namespace topocal::calib::testing

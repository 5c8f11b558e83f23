#include "pipeline/measure_spots.h"

#include <stdexcept>

#include <fmt/format.h>

#include "correct/detect_and_index.h"
#include "correct/undistort_points.h"

namespace topocal::pipeline {

SpotMeasurement MeasureSpots(const cv::Mat& image, const model::TopographerCamera& camera,
                             const model::IdealImageParams& ideal, const std::optional<model::Distortion>& distortion) {
  const auto located = correct::DetectAndIndexSpots(image, camera, ideal);
  if (!located.ok) throw std::runtime_error(fmt::format("spot detection/indexing: {}", located.message));
  SpotMeasurement m;
  m.indexed = static_cast<int>(located.spots.size());
  m.unassigned = static_cast<int>(located.unassigned.size());
  m.missing = static_cast<int>(located.missing.size());
  for (const auto& s : located.spots) m.detected.push_back({s.id, s.position_mm});
  if (!distortion) {
    for (const auto& s : located.spots) m.spots.push_back({s.id, s.position_mm});
    return m;
  }
  std::vector<Eigen::Vector2d> distorted;
  distorted.reserve(located.spots.size());
  for (const auto& s : located.spots) distorted.push_back(s.position_mm);
  const auto undistorted = correct::UndistortPoints(*distortion, distorted);
  m.undistort_failures = static_cast<int>(undistorted.failures.size());
  for (size_t i = 0; i < located.spots.size(); ++i) {
    if (undistorted.ok[i]) m.spots.push_back({located.spots[i].id, undistorted.points_mm[i]});
  }
  return m;
}

}  // namespace topocal::pipeline

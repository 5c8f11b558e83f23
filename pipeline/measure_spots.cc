#include "pipeline/measure_spots.h"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>
#include <utility>

#include "correct/detect_and_index.h"
#include "correct/undistort_points.h"
#include "pipeline/surface_labelling.h"
#include "util/io.h"

namespace topocal::pipeline {

std::vector<topo::MeasuredSpot> UndistortSpots(const std::vector<MeasuredImageSpot>& detected,
                                               const model::Distortion& distortion, int* failures) {
  std::vector<Eigen::Vector2d> distorted;
  distorted.reserve(detected.size());
  for (const auto& s : detected) distorted.push_back(s.distorted_mm);
  const auto undistorted = correct::UndistortPoints(distortion, distorted);
  if (failures) *failures = static_cast<int>(undistorted.failures.size());
  std::vector<topo::MeasuredSpot> spots;
  spots.reserve(detected.size());
  for (size_t i = 0; i < detected.size(); ++i) {
    if (undistorted.ok[i]) spots.push_back({detected[i].id, undistorted.points_mm[i]});
  }
  return spots;
}

bool FreeDetectionIsSpotLike(const correct::LocatedSpot& free, const std::vector<correct::LocatedSpot>& identified) {
  std::vector<std::pair<double, double>> near;  // (distance, flux)
  for (const auto& s : identified) near.emplace_back((s.position_mm - free.position_mm).norm(), s.flux_dn);
  const size_t n = std::min<size_t>(kFreeFluxNeighbours, near.size());
  if (n == 0) return true;
  std::partial_sort(near.begin(), near.begin() + n, near.end());
  std::vector<double> flux;
  for (size_t k = 0; k < n; ++k) flux.push_back(near[k].second);
  std::sort(flux.begin(), flux.end());
  const double median = n % 2 ? flux[n / 2] : 0.5 * (flux[n / 2 - 1] + flux[n / 2]);
  return free.flux_dn >= kFreeFluxLow * median && free.flux_dn <= kFreeFluxHigh * median;
}

IdentifiedSpots IdentifySpots(const cv::Mat& image, const model::TopographerCamera& camera,
                              const model::IdealImageParams& ideal, const correct::DetectAndIndexOptions& options) {
  IdentifiedSpots out;
  out.located = correct::DetectAndIndexSpots(image, camera, ideal, options);
  const correct::DetectAndIndexResult& located = out.located;
  if (located.orientation.status == correct::OrientationCheck::Status::kMismatch) {
    throw util::InputError(located.orientation.message);
  }
  out.capture = AssessCapture(located, camera, ideal);
  if (!located.ok || out.capture.visible_fraction < kMinVisibleFraction) {
    throw util::MeasurementRefused(fmt::format(
        "measurement refused: spot identification: {} ({:.0f} % of the designed spots identified, need {:.0f} %); {}",
        located.message, 100 * out.capture.visible_fraction, 100 * kMinVisibleFraction, out.capture.Line()));
  }
  return out;
}

SpotMeasurement MeasureSpots(const cv::Mat& image, const model::TopographerCamera& camera,
                             const model::IdealImageParams& ideal, const std::optional<model::Distortion>& distortion,
                             const correct::DetectAndIndexOptions& options) {
  auto identified = IdentifySpots(image, camera, ideal, options);
  const correct::DetectAndIndexResult& located = identified.located;
  SpotMeasurement m;
  m.capture = std::move(identified.capture);
  m.excluded = static_cast<int>(located.excluded.size());
  m.orientation_message = located.orientation.message;
  m.indexed = static_cast<int>(located.spots.size());
  m.unassigned = static_cast<int>(located.unassigned.size());
  m.missing = static_cast<int>(located.missing.size());
  m.missing_ids = located.missing;
  for (const auto& s : located.unassigned) {
    if (!(s.flags & options.exclude_flags) && FreeDetectionIsSpotLike(s, located.spots)) {
      m.free_mm.push_back(s.position_mm);
    }
  }
  for (const auto& s : located.spots) m.detected.push_back({s.id, s.position_mm});
  if (!distortion) {
    for (const auto& s : located.spots) m.spots.push_back({s.id, s.position_mm});
    return m;
  }
  m.spots = UndistortSpots(m.detected, *distortion, &m.undistort_failures);
  return m;
}

SpotMeasurement MeasureSpots(const cv::Mat& image, const model::Device& device, const model::IdealImageParams& ideal,
                             const correct::DetectAndIndexOptions& options) {
  return MeasureSpots(image, device.camera, ideal, device.distortion, options);
}

EyeMeasurement MeasureEye(const cv::Mat& image, const model::Device& device, const model::Config& config,
                          const correct::DetectAndIndexOptions& options, const model::BiconicParams* truth) {
  EyeMeasurement m;
  m.spots = MeasureSpots(image, device, config.ideal_image, options);
  const auto analyze = [&](const std::vector<topo::MeasuredSpot>& spots) {
    return AnalyzeThroughDevice(spots, device, config, truth);
  };
  m.analysis = LabelThroughSurface(&m.spots, device, config, analyze);
  m.verdict = JudgeMeasurement(m.spots.capture, m.analysis);
  return m;
}

topo::Analysis AnalyzeThroughDevice(const std::vector<topo::MeasuredSpot>& spots, const model::Device& device,
                                    const model::Config& config, const model::BiconicParams* truth,
                                    const topo::AnalysisOptions& options) {
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  model::Config as_built = config;
  as_built.topographer = device.AsBuilt(config.topographer);
  return topo::AnalyzeSpots(spots, device.PlaceTargets(design.targets, config.topographer), as_built, truth, options);
}

}  // namespace topocal::pipeline

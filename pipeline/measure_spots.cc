#include "pipeline/measure_spots.h"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <set>
#include <stdexcept>
#include <utility>

#include "correct/detect_and_index.h"
#include "correct/undistort_points.h"
#include "imageio/image_file.h"
#include "pipeline/surface_labelling.h"
#include "util/io.h"

namespace topocal::pipeline {

std::vector<model::PlaneSpot> UndistortSpots(const std::vector<model::PlaneSpot>& detected,
                                               const model::Distortion& distortion, int* failures) {
  std::vector<Eigen::Vector2d> distorted;
  distorted.reserve(detected.size());
  for (const auto& s : detected) distorted.push_back(s.position_mm);
  const auto undistorted = correct::UndistortPoints(distortion, distorted);
  if (failures) *failures = static_cast<int>(undistorted.failures.size());
  std::vector<model::PlaneSpot> spots;
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

SpotMeasurement MeasurementOf(const IdentifiedSpots& identified, const std::optional<model::Distortion>& distortion,
                              const correct::DetectAndIndexOptions& options) {
  const correct::DetectAndIndexResult& located = identified.located;
  SpotMeasurement m;
  m.capture = identified.capture;
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
  m.detected = model::PlaneSpotsOf(located.spots);
  if (!distortion) {
    m.spots = m.detected;
    return m;
  }
  m.spots = UndistortSpots(m.detected, *distortion, &m.undistort_failures);
  return m;
}

cv::Mat ReadSpotImage(const std::string& path, const model::TopographerCamera& camera, const std::string& camera_file) {
  cv::Mat image = imageio::ReadImage(path, imageio::Channels::kAsStored);
  imageio::RequireSize(image, path, camera.width_px, camera.height_px, camera_file);
  return image;
}

SpotMeasurement MeasureSpots(const cv::Mat& image, const model::TopographerCamera& camera,
                             const model::IdealImageParams& ideal, const std::optional<model::Distortion>& distortion,
                             const correct::DetectAndIndexOptions& options) {
  return MeasurementOf(IdentifySpots(image, camera, ideal, options), distortion, options);
}

SpotMeasurement MeasureSpots(const cv::Mat& image, const model::Device& device, const model::IdealImageParams& ideal,
                             const correct::DetectAndIndexOptions& options) {
  return MeasureSpots(image, device.camera, ideal, device.distortion, options);
}

EyeMeasurement MeasureEye(const cv::Mat& image, const model::Device& device, const model::Config& config,
                          const correct::DetectAndIndexOptions& options, const model::BiconicParams* truth) {
  EyeMeasurement m;
  m.spots = MeasureSpots(image, device, config.ideal_image, options);
  m.verdict = LabelAndJudge(&m.spots, device, config, AnalysisOf(&device, config, truth), &m.analysis);
  return m;
}

model::Config ForEyes(model::Config config) {
  if (!config.reconstruction.surface_model_given) config.reconstruction.surface_model = "auto";
  return config;
}

SpotAnalysis AnalysisOf(const model::Device* device, const model::Config& config, const model::BiconicParams* truth) {
  if (device) {
    return [device = *device, config, truth](const std::vector<model::PlaneSpot>& spots) {
      return AnalyzeThroughDevice(spots, device, config, truth);
    };
  }
  return [design = model::DesignNullScreen(config.ideal_image, config.topographer), config,
          truth](const std::vector<model::PlaneSpot>& spots) {
    return topo::AnalyzeSpots(spots, design.targets, config, truth);
  };
}

MeasurementVerdict LabelAndJudge(SpotMeasurement* m, const model::Device& imaging, const model::Config& config,
                                 const SpotAnalysis& analyze, topo::Analysis* analysis) {
  try {
    *analysis = LabelThroughSurface(m, imaging, config, analyze);
  } catch (const std::runtime_error& e) {
    *analysis = {};
    return {false, {fmt::format("the identified spots give no surface: {}", e.what())}};
  }
  return JudgeMeasurement(m->capture, *analysis);
}

namespace {

// Where a detection sits in `v` (bitwise the same position: the measurement copies it), or -1.
int FindAt(const std::vector<correct::LocatedSpot>& v, const Eigen::Vector2d& mm) {
  for (size_t i = 0; i < v.size(); ++i) {
    if (v[i].position_mm == mm) return static_cast<int>(i);
  }
  return -1;
}

}  // namespace

correct::DetectAndIndexResult WithSurfaceIdentities(const correct::DetectAndIndexResult& located,
                                                    const SpotMeasurement& labelled) {
  correct::DetectAndIndexResult out = located;
  std::vector<correct::LocatedSpot> identified = out.spots;
  std::set<model::SpotId> before;
  for (const auto& s : located.spots) before.insert(s.id);
  for (const auto& d : labelled.detected) {
    if (before.count(d.id)) continue;
    const int k = FindAt(out.unassigned, d.position_mm);
    if (k < 0) continue;  // cannot happen: every surface identity is a free detection's position
    correct::LocatedSpot s = out.unassigned[k];
    s.id = d.id;
    s.flags |= correct::kSurfaceLabelled;
    identified.push_back(s);
    out.unassigned.erase(out.unassigned.begin() + k);
    std::erase(out.missing, d.id);
  }
  const std::set<model::SpotId> outliers(labelled.capture.surface_outliers.begin(),
                                         labelled.capture.surface_outliers.end());
  out.spots.clear();
  for (auto& s : identified) {
    if (outliers.count(s.id)) {
      s.flags |= correct::kSurfaceOutlier;
      out.excluded.push_back(s);
    } else {
      out.spots.push_back(s);
    }
  }
  const auto by_id = [](const correct::LocatedSpot& a, const correct::LocatedSpot& b) { return a.id < b.id; };
  std::sort(out.spots.begin(), out.spots.end(), by_id);
  std::sort(out.excluded.begin(), out.excluded.end(), by_id);
  return out;
}

CheckedSpots DetectThroughSurface(const cv::Mat& image, const model::Device& imaging, bool undistort,
                                  const SpotAnalysis& analyze, const model::Config& config,
                                  const correct::DetectAndIndexOptions& options) {
  const IdentifiedSpots identified = IdentifySpots(image, imaging.camera, config.ideal_image, options);
  SpotMeasurement m = MeasurementOf(identified, undistort ? std::optional(imaging.distortion) : std::nullopt, options);
  topo::Analysis analysis;
  CheckedSpots out;
  out.verdict = LabelAndJudge(&m, imaging, config, analyze, &analysis);
  out.located = WithSurfaceIdentities(identified.located, m);
  out.capture = m.capture;
  if (out.verdict.valid) {
    out.flagged_identities_dropped = CheckFlaggedIdentities(&out.located, analysis.reconstruction, imaging, config);
  }
  return out;
}

int CheckFlaggedIdentities(correct::DetectAndIndexResult* located, const topo::Reconstruction& surface,
                           const model::Device& imaging, const model::Config& config) {
  if (located->excluded.empty()) return 0;
  std::vector<model::SpotId> ids;
  for (const auto& t : model::DesignNullScreen(config.ideal_image, config.topographer).targets) ids.push_back(t.id);
  const auto predictions = PredictSpots(surface, ids, imaging, config);
  int next_blob = 0;
  for (const auto& u : located->unassigned) next_blob = std::max(next_blob, u.id.index + 1);
  std::vector<correct::LocatedSpot> kept;
  int dropped = 0;
  for (const auto& s : located->excluded) {
    const PredictedSpot* nearest = nullptr;
    for (const auto& p : predictions) {
      if (!nearest || (p.position_mm - s.position_mm).squaredNorm() <
                          (nearest->position_mm - s.position_mm).squaredNorm()) {
        nearest = &p;
      }
    }
    double spacing = std::numeric_limits<double>::infinity();  // from its prediction to the next one
    for (const auto& p : predictions) {
      if (nearest && &p != nearest) spacing = std::min(spacing, (p.position_mm - nearest->position_mm).norm());
    }
    if (nearest && nearest->id == s.id && (nearest->position_mm - s.position_mm).norm() <= kGateSpacings * spacing) {
      kept.push_back(s);
      continue;
    }
    correct::LocatedSpot blob = s;
    blob.id = {0, next_blob++};
    located->unassigned.push_back(blob);
    located->missing.push_back(s.id);
    ++dropped;
  }
  located->excluded = std::move(kept);
  std::sort(located->missing.begin(), located->missing.end());
  return dropped;
}

}  // namespace topocal::pipeline

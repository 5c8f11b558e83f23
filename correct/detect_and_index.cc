#include "correct/detect_and_index.h"

namespace topocal::correct {

std::vector<model::ImageSpot> DetectAndIndexResult::AsImageSpots() const {
  std::vector<model::ImageSpot> out;
  out.reserve(spots.size());
  for (const auto& s : spots) {
    model::ImageSpot is;
    is.id = s.id;
    is.position_mm = s.position_mm;
    is.on_surface_mm.setZero();
    out.push_back(is);
  }
  return out;
}

DetectAndIndexResult DetectAndIndexSpots(const cv::Mat& image, const model::TopographerCamera& camera,
                                         const model::IdealImageParams& ideal, const DetectAndIndexOptions& options) {
  DetectAndIndexResult out;
  out.detection = DetectSpots(image, options.detection);
  std::vector<Eigen::Vector2d> mm;
  mm.reserve(out.detection.spots.size());
  for (const auto& s : out.detection.spots) mm.push_back(camera.DetectionPlaneFromPixel(s.centre_px));
  const SpotIndexing idx = IndexSpots(mm, ideal, options.indexing);
  for (const auto& s : idx.spots) {
    out.spots.push_back({s.id, out.detection.spots[s.detection].centre_px, mm[s.detection]});
  }
  for (const int i : idx.unassigned_detections) {
    out.unassigned.push_back({model::SpotId{0, i}, out.detection.spots[i].centre_px, mm[i]});
  }
  out.missing = idx.missing;
  out.index_residual_rms_mm = idx.residual_rms;
  out.ok = idx.ok;
  out.message = idx.message;
  return out;
}

}  // namespace topocal::correct

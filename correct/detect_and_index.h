#pragma once
// The raw-image entry point: detect the spots of a sensor image, convert their centres to detection-plane
// millimetres with the topographer's camera, and give each its (ring, index) identity.
//
// Positions are as the camera saw them, i.e. still DISTORTED: undistort them with correct::UndistortPoints and a
// calibrated model::Distortion before reconstructing.
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "correct/spot_detect.h"
#include "correct/spot_index.h"
#include "model/config.h"
#include "model/null_screen.h"
#include "model/topographer_camera.h"

namespace topocal::correct {

struct LocatedSpot {
  model::SpotId id;  // ring 0 for an unassigned detection
  Eigen::Vector2d position_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d position_mm = Eigen::Vector2d::Zero();  // detection plane, paper frame
};

struct DetectAndIndexOptions {
  SpotDetectionOptions detection;
  IndexingOptions indexing;
};

struct DetectAndIndexResult {
  std::vector<LocatedSpot> spots;       // identified, sorted by id
  std::vector<LocatedSpot> unassigned;  // detections without identity (spurious blobs), ring = 0
  std::vector<model::SpotId> missing;   // designed spots not found
  SpotDetection detection;              // background, noise, threshold, rejected blobs
  double index_residual_rms_mm = 0;
  bool ok = false;
  std::string message;
  // The identified spots as model::ImageSpot (position_mm only; on_surface_mm is unknown and zero).
  std::vector<model::ImageSpot> AsImageSpots() const;
};

// Throws std::invalid_argument for an unusable image type or invalid options; never for what the image contains.
DetectAndIndexResult DetectAndIndexSpots(const cv::Mat& image, const model::TopographerCamera& camera,
                                         const model::IdealImageParams& ideal,
                                         const DetectAndIndexOptions& options = {});

}  // namespace topocal::correct

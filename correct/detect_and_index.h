#pragma once
// The raw-image entry point: detect the spots of a sensor image, convert their centres to detection-plane
// millimetres with the topographer's camera, and give each its (ring, index) identity.
//
// Flagged spots (correct/spot_detect.h, SpotFlag): spots near another blob or cut by the border keep their identity
// but are moved to `excluded` (options.exclude_flags), so the measurement — every consumer of `spots`, i.e.
// pipeline::MeasureSpots and the reconstruction after it — leaves them out; saturated spots stay (the PSF fit leaves
// their clipped pixels out).
//
// Orientation: with the orientation key (ideal_image.orientation_key) the key's gaps must be where the declared
// orientation puts them; otherwise the result is refused (ok = false, orientation.status kMismatch, the message
// naming the orientation the image appears to have). Without the key it cannot be checked (kNotKeyed).
//
// Positions are as the camera saw them, i.e. still DISTORTED: undistort them with correct::UndistortPoints and a
// calibrated model::Distortion before reconstructing.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "correct/spot_detect.h"
#include "correct/spot_index.h"
#include "model/config.h"
#include "model/null_screen.h"
#include "model/topographer_camera.h"
#include "util/io.h"

namespace topocal::correct {

struct LocatedSpot {
  model::SpotId id;  // ring 0 for an unassigned detection (index: its number among the detections)
  unsigned flags = 0;  // SpotFlag bits of the detection
  Eigen::Vector2d position_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d position_mm = Eigen::Vector2d::Zero();  // detection plane, paper frame
  int area_px = 0;   // pixels above the detection threshold
  double flux_dn = 0;  // background-subtracted light in the window
};

struct DetectAndIndexOptions {
  SpotDetectionOptions detection;
  IndexingOptions indexing;
  unsigned exclude_flags = kNearBlob | kTruncated | kFluxOutlier | kUnevenBackground;
  // kFluxOutlier when a spot's light (flux_dn) is below flux_low or above flux_high times the median of its
  // identified neighbours on the same ring (two on either side; at least three needed to judge).
  double flux_low = 0.8, flux_high = 1.5;
};

struct OrientationCheck {
  enum class Status { kNotKeyed, kConfirmed, kMismatch, kUndetermined };
  Status status = Status::kNotKeyed;
  int key_spots = 0;      // gaps of the key
  int key_occupied = 0;   // of them, identities a detection took (0 when the orientation is right)
  std::optional<model::ImageOrientation> apparent;  // kMismatch: the orientation the image appears to have
  std::string message;    // one line for the measurement's output
};

struct DetectAndIndexResult {
  std::vector<LocatedSpot> spots;       // identified and usable, sorted by id
  std::vector<LocatedSpot> excluded;    // identified but flagged (exclude_flags): left out of the measurement
  std::vector<LocatedSpot> unassigned;  // detections without identity (spurious blobs), ring = 0
  std::vector<model::SpotId> missing;   // designed spots not found
  SpotDetection detection;              // background, noise, threshold, rejected blobs
  OrientationCheck orientation;
  double index_residual_rms_mm = 0;
  int refused_identities = 0;           // identities the indexer's checks refused (ambiguous or inconsistent)
  bool ok = false;
  std::string message;
  // The identified spots as model::ImageSpot (position_mm only; on_surface_mm is unknown and zero).
  std::vector<model::ImageSpot> AsImageSpots() const;
};

// Throws util::InputError for an unusable image type or invalid options; never for what the image contains.
DetectAndIndexResult DetectAndIndexSpots(const cv::Mat& image, const model::TopographerCamera& camera,
                                         const model::IdealImageParams& ideal,
                                         const DetectAndIndexOptions& options = {});

}  // namespace topocal::correct

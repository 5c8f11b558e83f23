#pragma once
// The fit of the camera calibration (calib/calibrate.cc): the Ceres problem over the camera, the views' poses and the
// board warp, solved with optional outlier rejection, and the result's statistics, covariance and parameters.
// Private to calib/calibrate*.cc.
#include <array>
#include <string>
#include <vector>

#include "calib/calibrate.h"
#include "calib/cost_functions.h"

namespace topocal::calib::internal {

// Indices into the parameter table (CameraParameterNames): the intrinsics, then the lens model's coefficients from
// kDist, then the centre's two at CentreIndex(lens).
enum ParamIndex : int { kFx, kFy, kCx, kCy, kDist };
inline int CentreIndex(const model::LensModelId& lens) { return kDist + model::LensParameterCount(lens); }

struct Parameters {
  model::LensModelId lens;
  std::array<double, kNumIntrinsics> intrinsics{};
  model::LensCoefficients dist{};
  std::array<double, kNumCentre> centre{};
  std::vector<std::array<double, kNumPose>> poses;  // one per used view
  std::array<double, kNumWarp> warp{};                // sag_x, sag_y mm (held at 0 unless fitted)
  BoardWarp warp_geometry;
};

// A view that takes part in the fit, with the inlier flag of each of its corners.
struct UsedView {
  int index = 0;
  const ViewObservations* view = nullptr;
  std::vector<bool> inlier;
};

// Per entry of the parameter table: fitted (true) or held.
using FreeMask = std::vector<bool>;

inline CalibrationResult Failure(CalibrationStatus status, std::string message) {
  CalibrationResult r;
  r.status = status;
  r.message = std::move(message);
  return r;
}

// Solves, optionally rejecting outliers, then fills the statistics and the covariance of `result`.
CalibrationResult SolveAndReport(Parameters& p, std::vector<UsedView>& views, const FreeMask& free,
                                 const CalibrationOptions& o, CalibrationResult result);

}  // namespace topocal::calib::internal

#pragma once
// Whether the views determine a fitted camera parameter at all. A standard deviation larger than the whole range a
// lens could give the parameter means the data did not bound it: the value is whatever the solver stopped at (a
// single view of a small board fits k3 = -22.5 +- 266). Such a parameter is reported as undetermined, with the
// advice to hold it fixed or add views, and a unit calibration refuses it unless told (docs/calibration.md).
//
// The plausible range of each parameter, from the calibrated camera's own geometry (r_c: the largest normalised
// radius of an image corner from the principal point):
//   fx, fy     +- half the focal length (a focal length not known to within a factor of 2 is not known)
//   cx, cy     +- half the image width / height (the principal point anywhere on the sensor)
//   k1, k2, k3 +- 1 / r_c^2, 1 / r_c^4, 1 / r_c^6 (the term alone moves the image corner by its own distance from
//              the principal point: beyond that the model folds the image onto itself)
//   k4, k5, k6 the same as k1, k2, k3 (the rational model's denominator, term for term)
//   p1, p2     +- 1 / (3 r_c) (the tangential terms' largest displacement at the corner, 3 p r_c^2, the same bound)
//   ex, ey     +- r_c (the distortion centre anywhere on the image)
#include <string>
#include <string_view>
#include <vector>

#include "calib/calibrate.h"

namespace topocal::calib {

struct UndeterminedParameter {
  std::string name;
  double value = 0, stddev = 0;
  double plausible_half_range = 0;  // in the parameter's own units
};

// The plausible half range of parameter `name` (CameraParameterNames) for `camera`; 0 for an unknown name.
double PlausibleHalfRange(std::string_view name, const model::CameraModel& camera);

// The free parameters of a successful calibration whose standard deviation exceeds their plausible half range, in
// the result's parameter order; empty when every free parameter is determined (or the calibration failed).
std::vector<UndeterminedParameter> UndeterminedParameters(const CalibrationResult& result);

// One line: "k3 = -22.5 +- 266 (plausible +-5.6)[, ...]: the views do not determine it; hold it fixed (--fix k3) or
// add views covering the image".
std::string UndeterminedMessage(const std::vector<UndeterminedParameter>& undetermined);

}  // namespace topocal::calib

#include "calib/calibrate.h"

// The calibration's names (distortion models, robust losses, statuses, parameter tables) apart from the fit, in a
// file of their own: readers of calibration files and of devices use them, and a program linking the fit's object
// for them would load OpenCV's calib3d (and its features2d and flann) with it.
namespace topocal::calib {

std::string_view ToString(const DistortionModelKind& model) noexcept {
  return model.seidel ? "seidel" : model::LensModelName(model.lens);
}

std::optional<DistortionModelKind> ParseDistortionModel(std::string_view name) noexcept {
  if (name == "seidel") return DistortionModelKind::kSeidel;
  if (const auto lens = model::LensModelFromName(name)) return DistortionModelKind{false, *lens};
  return std::nullopt;
}

std::string DistortionModelNames() { return "seidel, " + model::LensModelNames(); }

std::vector<std::string> CameraParameterNames(const DistortionModelKind& model) {
  std::vector<std::string> names = {"fx", "fy", "cx", "cy"};
  for (const auto name : model::LensParameterNames(model.lens)) names.emplace_back(name);
  names.insert(names.end(), {"ex", "ey"});
  return names;
}

std::string_view ToString(RobustLoss loss) noexcept {
  switch (loss) {
    case RobustLoss::kHuber: return "huber";
    case RobustLoss::kCauchy: return "cauchy";
    case RobustLoss::kNone: break;
  }
  return "none";
}

std::optional<RobustLoss> ParseRobustLoss(std::string_view name) noexcept {
  if (name == "none") return RobustLoss::kNone;
  if (name == "huber") return RobustLoss::kHuber;
  if (name == "cauchy") return RobustLoss::kCauchy;
  return std::nullopt;
}

std::string_view ToString(CalibrationStatus status) noexcept {
  switch (status) {
    case CalibrationStatus::kOk: return "ok";
    case CalibrationStatus::kInvalidOptions: return "invalid options";
    case CalibrationStatus::kInvalidInput: return "invalid input";
    case CalibrationStatus::kTooFewViews: return "too few views";
    case CalibrationStatus::kTooFewCorners: return "too few corners";
    case CalibrationStatus::kDegenerate: return "degenerate";
    case CalibrationStatus::kSolverFailed: return "solver failed";
    case CalibrationStatus::kCovarianceFailed: return "covariance failed";
  }
  return "unknown";
}

}  // namespace topocal::calib

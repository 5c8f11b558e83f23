// The estimator's names, in an object of their own: the sweep's JSON writer (report/analysis_json.cc) names the
// estimator, and linking spot_detect.cc for that would bring OpenCV into topocal-sweep, which links none
// (docs/startup.md).
#include <fmt/format.h>

#include "correct/spot_detect.h"
#include "util/io.h"

namespace topocal::correct {

CentroidMethod CentroidMethodFromName(const std::string& name) {
  if (name == "centroid") return CentroidMethod::kIntensityWeighted;
  if (name == "gaussian") return CentroidMethod::kGaussianFit;
  if (name == "psf") return CentroidMethod::kWeightedPsfFit;
  throw util::InputError(fmt::format("unknown estimator '{}' (centroid, gaussian or psf)", name));
}

const char* CentroidMethodName(CentroidMethod method) noexcept {
  switch (method) {
    case CentroidMethod::kIntensityWeighted: return "centroid";
    case CentroidMethod::kGaussianFit: return "gaussian";
    case CentroidMethod::kWeightedPsfFit: return "psf";
  }
  return "?";
}

}  // namespace topocal::correct

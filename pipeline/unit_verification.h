#pragma once
// What a unit's calibration is worth, in clinical numbers: the two checks of a unit record
// (docs/unit-record.md).
//
//  * Reference sphere: the raw image of a precision ball of known radius, measured by the unit, reconstructed
//    without and with the calibration. A sphere's radius and power are known exactly, so the errors are the unit's
//    own measurement errors — the check topographer makers and ISO 19980 use on test surfaces.
//  * Paper cornea: the configuration's biconic imaged, in simulation, through the unit's camera as calibrated —
//    uncorrected (its distortion left in) and corrected (undistorted with the calibration), the calibration's
//    covariance carried through (pipeline/uncertainty.h). It says what this unit's distortion would do to an aspheric,
//    astigmatic cornea, where the conic constants are fragile.
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <optional>

#include "calib/calibration_file.h"
#include "model/camera_model.h"
#include "model/config.h"
#include "model/topographer_camera.h"
#include "pipeline/uncertainty.h"
#include "topo/analysis.h"
#include "util/io.h"

namespace topocal::pipeline {

// One reconstruction in clinical numbers.
struct ClinicalNumbers {
  int spots = 0;
  double rx_mm = 0, ry_mm = 0, kx = 0, ky = 0, alpha_deg = 0;
  double radius_mm = 0;              // mean of rx and ry
  double central_axial_power_D = 0;  // topo::MeanAxialPowerD over kCentralPowerRadiusMm
  double pv_tangential_D = 0, pv_axial_D = 0;
  // Model adequacy (topo::Reconstruction): the slope residual over what spot-centre noise would leave, and its
  // part that neighbouring spots share; above topo::kAdequacyWarningRatio / kStructuredResidualWarningRatio the
  // surface model does not represent the spots (uncorrected distortion makes them non-integrable).
  double adequacy_ratio = 0, structured_residual_ratio = 0;
  std::optional<double> height_pv_um, height_rms_um;  // against the truth, when known
};
ClinicalNumbers Summarize(const topo::Analysis& analysis, int spots);

// The calibration of a unit as the checks need it.
struct UnitCalibration {
  model::CameraModel camera;  // the calibrated (exact) model, in pixels of the unit's sensor
  calib::ParameterCovariance covariance;
};

struct CheckOptions {
  UncertaintySetting uncertainty;  // linear propagation unless told (pipeline/uncertainty.h)
  std::uint32_t seed = 1;          // of the Monte Carlo draws
  int jobs = 0;                    // threads for the analyses (0 = every core); the result does not depend on it
};

struct StageResult {
  ClinicalNumbers numbers;
  topo::Analysis analysis;
};

struct SphereVerification {
  double radius_true_mm = 0;
  std::vector<model::PlaneSpot> detected;  // the identified spots as the camera saw them (the record keeps them)
  double power_true_D = 0;  // (n_k - 1) / R, n_k = topo::kKeratometricIndex
  int spots_indexed = 0, spots_unassigned = 0, spots_missing = 0, undistort_failures = 0;
  StageResult uncorrected, corrected;
  std::optional<ClinicalUncertainty> uncertainty;  // of the corrected numbers
  double RadiusErrorMm(const StageResult& s) const { return s.numbers.radius_mm - radius_true_mm; }
  double PowerErrorD(const StageResult& s) const { return s.numbers.central_axial_power_D - power_true_D; }
};

// The design (`config`) with its cornea replaced by a sphere of this radius, fitted as a sphere
// (reconstruction.biconic_fit = "sphere": centre and radius; k_x = k_y = alpha = 0 by construction).
model::Config WithSphere(const model::Config& config, double radius_mm);

// Throws util::InputError for a non-physical radius or an image of the wrong size, std::runtime_error (one
// line) when the spots cannot be found, the reconstruction fails or the uncertainty cannot be propagated (the
// uncertainty is left out only when no distortion parameter has a spread: DistortionParametersToDraw).
SphereVerification VerifyOnReferenceSphere(const cv::Mat& image, double radius_mm, const UnitCalibration& unit,
                                           const model::TopographerCamera& camera, const model::Config& config,
                                           const CheckOptions& options);

// The first half of VerifyOnReferenceSphere: the checks of the radius and the image, and the spots detected and
// identified (`detected` and the detector's counts; nothing else set). It needs no calibration, so the unit
// workflow runs it while the camera is being calibrated. Same exceptions as VerifyOnReferenceSphere.
SphereVerification DetectReferenceSphere(const cv::Mat& image, double radius_mm, const model::TopographerCamera& camera,
                                         const model::Config& config);

// The same check from spots already detected and identified (`v.detected` and the detector's counts in `v`, the
// rest of `v` ignored): what VerifyOnReferenceSphere does after detection, and what the QA report recomputes from
// the record's sphere_spots.csv. Same exceptions, util::InputError also for an empty spot list.
SphereVerification VerifyOnReferenceSphere(SphereVerification v, double radius_mm, const UnitCalibration& unit,
                                           const model::TopographerCamera& camera, const model::Config& config,
                                           const CheckOptions& options);

struct SimulatedCornea {
  model::BiconicParams truth;
  StageResult uncorrected, corrected;
  std::optional<ClinicalUncertainty> uncertainty;
  double max_displacement_um = 0;  // largest shift the calibrated distortion gives a spot of this cornea
};

// Throws std::runtime_error when the calibrated distortion cannot be put on the detection plane, a reconstruction
// fails or the uncertainty cannot be propagated.
SimulatedCornea SimulateThroughCalibratedCamera(const UnitCalibration& unit, const model::TopographerCamera& camera,
                                                const model::Config& config, const CheckOptions& options);

}  // namespace topocal::pipeline

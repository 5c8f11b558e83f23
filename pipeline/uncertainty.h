#pragma once
// Calibration uncertainty carried to the clinical numbers: move the calibrated distortion parameters within their
// covariance, undistort the measured spots with each moved calibration, reconstruct, fit, map — and report each
// clinical number with its expanded uncertainty U = 2 u (k = 2). Two methods (GUM, JCGM 100:2008 Sec. 5.1, and its
// Supplement 1, JCGM 101:2008):
//
//   linear       u^2 = J S J', evaluated without forming J: along each eigen-direction v_j of S with a spread, the
//                spots are analysed with the calibration moved by +sqrt(l_j) v_j and by -sqrt(l_j) v_j, and
//                u^2 = sum_j ((q+ - q-) / 2)^2 (central differences: the curvature of q cancels). Two analyses per
//                direction; the reported mean is the calibration's own value. The default.
//   Monte Carlo  N seeded draws of joint normals with the covariance; mean and U = 2 s over the draws. A cross-check
//                of the linear result, and the method for a reading far from linear over the covariance.
//
// The parameters are moved jointly with the calibration's covariance (calibration files since topocal 0.1.0
// store it; for an older file calib::ParameterCovarianceOf gives the diagonal and `correlated` is false). Only the
// distortion parameters (k1..k3, p1, p2, ex, ey) are moved; the intrinsics enter the detection-plane distortion
// only through its scale, which the topographer's camera description fixes. The result says what was moved.
#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibration_file.h"
#include "model/camera_model.h"
#include "model/config.h"
#include "model/null_screen.h"
#include "model/topographer_camera.h"
#include "pipeline/measure_spots.h"
#include "util/io.h"

namespace topocal::pipeline {

// Monte Carlo draws of an uncertainty: the range of unit --uncertainty and of unit-inputs.json's
// uncertainty_samples (200 draws take ~0.5 s of CPU for a unit; 1e5 bounds the work at a few minutes per unit).
inline constexpr int kMaxUncertaintySamples = 100000;

// How a unit's checks carry the calibration's covariance to their clinical numbers.
struct UncertaintySetting {
  enum class Method { kNone, kLinear, kMonteCarlo };
  Method method = Method::kLinear;
  int draws = 0;  // kMonteCarlo: 2 to kMaxUncertaintySamples
  // "linear"; "none" or "0"; or a number of Monte Carlo draws, 2 to kMaxUncertaintySamples. util::InputError naming
  // `key` otherwise.
  static UncertaintySetting Parse(const std::string& text, const std::string& key);
  std::string MethodName() const;  // "none", "linear" or "monte-carlo"
  // The setting `MethodName()` and `draws` describe (a record's settings); nullopt when they do not go together.
  static std::optional<UncertaintySetting> FromName(const std::string& method, int draws);
  // Why FromName(method, draws) has none, in words.
  static std::string WhyNot(const std::string& method, int draws);
};

// The eigen-directions of a covariance with a spread, each scaled by its standard deviation: sqrt(l_j) v_j for the
// eigenvalues l_j > 1e-14 of the largest. The directions along which linear propagation moves the parameters.
// std::runtime_error when the matrix cannot be factored.
std::vector<Eigen::VectorXd> ScaledEigenDirections(const Eigen::MatrixXd& covariance);

// The central zone of the power reading: 3 mm diameter, the zone keratometers and topographers' simulated-K
// readings use (the Javal–Schiøtz keratometer measures at about 3 mm).
inline constexpr double kCentralPowerRadiusMm = 1.5;

struct ClinicalUncertainty {
  struct Quantity {
    double mean = 0;         // linear: the calibration's own value; Monte Carlo: the mean over the draws
    double expanded_k2 = 0;  // U = 2 u
  };
  bool linear = false;                // linear propagation (else Monte Carlo)
  int samples = 0;                    // linear: eigen-directions analysed; Monte Carlo: draws that reconstructed
  int failed_samples = 0;             // draws whose reconstruction failed (reported, not hidden; linear: always 0)
  // Spots an analysis could not undistort (the inverse distortion did not converge: a spot beyond the moved
  // distortion's fold) and so left out of its reconstruction, summed over the analyses; and how many lost any.
  int undistort_failures = 0;
  int draws_with_undistort_failures = 0;
  std::vector<std::string> drawn;     // parameter names moved
  bool correlated = false;            // moved with the full covariance (false: independent, diagonal only)
  // rx_mm, ry_mm, kx, ky, alpha_deg, pv_tangential_D, pv_axial_D, radius_mm (mean of rx, ry),
  // central_axial_power_D (topo::MeanAxialPowerD over kCentralPowerRadiusMm)
  std::map<std::string, Quantity> quantities;
};

// The distortion parameters of `covariance` that have a spread to draw (positive, finite variance), in the
// covariance's order. Empty means nothing to propagate (every distortion parameter fixed or without a reported
// standard deviation): the one legitimate "no uncertainty" case, which callers test for before propagating.
// Throws util::InputError when the matrix does not match its names.
std::vector<std::string> DistortionParametersToDraw(const calib::ParameterCovariance& covariance);

// `samples` 0: linear propagation; N >= 2: N Monte Carlo draws. The analyses run on `jobs` threads (<= 0: every
// core; util/parallel.h); draw i takes its normals from std::seed_seq{seed, i}, so the result is bit-identical
// whatever `jobs` is. Each analysis starts from the nominal one (the calibration as it is: topo::AnalysisOptions::start
// — its slope-fit factor, its surface for the first incidence points, its biconic or sphere fit) and computes only
// what the quantities need.
// Throws util::InputError for samples 1 or negative, a covariance whose size does not match its names, or no
// distortion parameter with a positive variance; std::runtime_error when the nominal analysis fails, any linear
// direction's analysis fails (an incomplete sum would understate U), or more than half of the draws fail.
ClinicalUncertainty PropagateCalibrationUncertainty(const std::vector<model::PlaneSpot>& spots,
                                                    const model::CameraModel& calibrated,
                                                    const calib::ParameterCovariance& covariance,
                                                    const model::TopographerCamera& camera, const model::Config& config,
                                                    int samples, std::uint32_t seed, int jobs = 0);

}  // namespace topocal::pipeline

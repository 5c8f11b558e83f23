#pragma once
// Calibration of the whole device (the paper's two stages at once: the pose of the null screen relative to the
// camera, then the lens distortion) from images of reference balls — precision spheres of certified radius placed
// roughly where the cornea goes. A Ceres bundle adjustment of
//
//   screen pose (rx, ry, rz deg about the mount; tx, ty, tz mm), optionally the screen's radial scale,
//   principal point (px), a (pinhole to detection plane, mm), distortion (Seidel sigma, or Brown k1, k2),
//   and every ball's vertex position (mm),
//
// to the identified spot centres of each ball image, through the exact forward model model::ProjectBallSpot
// (Eq. 14-16 reflected off the ball, Eq. 18 or Brown, the camera's pixel mapping). Residuals are in pixels divided by
// the spot-centre noise, so chi^2/dof is 1 when the model describes the images and the spot noise is as stated.
// Each device parameter has a Gaussian prior about its nominal value with the configured tolerance (a 1-sigma
// assembly tolerance); the balls' positions have a weak prior about their initial estimate.
//
// Gauge (docs/device.md): moving the balls and the cone together along the axis while a grows in proportion leaves
// every image (almost) unchanged, so one axial coordinate is not observable. It is fixed by a datum: the vertex z of
// one ball (the datum ball) is held at datum_z_mm (0: the nominal corneal vertex), which is also the reference the
// reconstruction measures from. Or by known stage steps between the balls (ball_steps_mm): how the images change
// with a known axial step depends on the distance from the pinhole, which the steps then measure.
//
// Balls alone cannot separate a lens model's decentring distortion (p1, p2) and its higher radial terms from a screen
// tilt: without target views they are held at their nominal values, and the fit says so in its notes. With target
// views (a planar target's corners, calib/observations.h, as `calibrate` detects them) every corner is a residual of
// the same fit through the same camera (model::ProjectPoint), each view's board pose a nuisance block, and every
// coefficient of the lens model is fitted with the pose.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calib/observations.h"
#include "model/config.h"
#include "model/device.h"
#include "model/null_screen.h"
#include "util/io.h"

namespace topocal::calib {

// One reference-ball image: its certified radius and the identified spot centres in raw pixels.
struct BallView {
  std::string name;   // the image, for messages
  double radius_mm = 0;
  std::vector<std::pair<model::SpotId, Eigen::Vector2d>> spots_px;
};

// One standard deviation of each prior, about the nominal device (assembly tolerances).
struct DeviceTolerances {
  double tilt_deg = 1.0;             // rx, ry
  double roll_deg = 2.0;             // rz
  double lateral_mm = 0.5;           // tx, ty
  double axial_mm = 1.0;             // tz
  double principal_point_mm = 0.1;   // on the sensor (divided by the pitch for pixels)
  double a_relative = 0.02;          // a / a_nominal - 1
  double radial_scale = 0.01;        // s - 1
  double sigma_per_mm2 = 1e-3;       // Seidel sigma (a weak prior: the balls determine it)
  double brown_k = 1.0;              // Brown k1, k2
  double ball_placement_mm = 1.0;    // each ball about its initial estimate
  bool IsValid(std::string* why) const;
};

struct DeviceFitOptions {
  DeviceTolerances priors;
  double spot_sigma_px = 0.04;       // noise of one spot centre, per axis
  double corner_sigma_px = 0.05;     // noise of one target corner, per axis (with target views)
  int datum_ball = 0;                // the ball whose vertex z is held at datum_z_mm
  double datum_z_mm = 0.0;
  // The alternative axial gauge: each ball's known position along the axis (a stage's readings, mm, in the order of
  // the balls; only their differences matter). The balls' vertices are then z = offset + step, the offset fitted,
  // and no ball's vertex is assumed to sit at the working position. Empty: the datum.
  std::vector<double> ball_steps_mm;
  bool fit_radial_scale = false;
  bool fit_distortion = true;
  // chi^2/dof above this: the model does not describe the images (e.g. an elliptical cone) — flagged, not hidden.
  double max_chi2_per_dof = 4.0;
  int max_iterations = 100;
  bool IsValid(std::string* why) const;
};

struct DeviceParameterEstimate {
  std::string name;   // e.g. "rx_deg", "principal_point_u_px", "sigma_per_mm2"
  double value = 0;
  double stddev = 0;
  double nominal = 0;
};

struct DeviceFit {
  bool ok = false;
  std::string message;                         // why it failed, or a one-line summary
  model::Device device;                        // the calibrated device
  std::vector<DeviceParameterEstimate> parameters;  // the fitted device parameters with standard deviations
  Eigen::MatrixXd covariance;                  // of `parameters`, in their order and units
  std::vector<Eigen::Vector3d> ball_vertex_mm;
  std::vector<Eigen::Vector3d> ball_vertex_stddev_mm;
  std::vector<double> ball_rms_px;             // per image: rms of |predicted - observed|
  std::vector<int> ball_spots;                 // per image: spots used
  std::vector<double> view_rms_px;             // per target view: rms of |predicted - observed| corner
  std::vector<int> view_corners;               // per target view: corners used
  double chi2_per_dof = 0;                     // spot residuals only (priors excluded)
  int dof = 0;
  double stddev_scale = 1;                     // max(1, sqrt(chi2/dof)): applied to the standard deviations
  bool model_adequate = true;
  std::string gauge;                           // how the axial gauge was fixed
  std::vector<std::string> notes;              // what was held and why
  int iterations = 0;
  // The value and standard deviation of a named parameter (nullopt if not fitted).
  std::optional<DeviceParameterEstimate> Parameter(const std::string& name) const;
  // `covariance` with its parameters' names: what a measurement through the device propagates.
  model::DeviceCovariance Covariance() const;
};

// Fits the device. Never throws: invalid options (the message starts "invalid options: "), too few balls or spots,
// or a solver failure give ok = false and a message, as the camera fit (calib/calibrate.h) reports its own.
// `views`: target views through the same camera (may be empty).
DeviceFit FitDevice(const model::Device& nominal, const model::TopographerParams& design,
                    const std::vector<model::TargetPoint>& designed_targets, const std::vector<BallView>& balls,
                    const DeviceFitOptions& options = {}, const std::vector<ViewObservations>& views = {});

}  // namespace topocal::calib

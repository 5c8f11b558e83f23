#pragma once
// Seeded synthetic corner sets for the fitting tests: a planar grid projected through a known CameraModel.
#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "calib/observations.h"
#include "calib/zhang.h"
#include "model/camera_model.h"

namespace topocal::calib::testing {

struct GridTarget {
  int cols = 11, rows = 8;
  double spacing_mm = 30.0;
};

inline ViewPose MakePose(double rx_deg, double ry_deg, double rz_deg, const Eigen::Vector3d& centre_in_cam_mm,
                              const GridTarget& grid) {
  constexpr double kDeg = M_PI / 180.0;
  const Eigen::Matrix3d r = (Eigen::AngleAxisd(rz_deg * kDeg, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(ry_deg * kDeg, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(rx_deg * kDeg, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  const Eigen::Vector3d grid_centre(0.5 * (grid.cols - 1) * grid.spacing_mm, 0.5 * (grid.rows - 1) * grid.spacing_mm,
                                    0);
  const Eigen::AngleAxisd aa(r);
  ViewPose pose;
  pose.angle_axis = aa.angle() * aa.axis();
  pose.translation_mm = centre_in_cam_mm - r * grid_centre;
  return pose;
}

// Projects every grid corner; corners outside the image are left out. noise_px: per-axis Gaussian sigma.
inline ViewObservations ProjectGrid(const model::CameraModel& camera, const ViewPose& pose, const GridTarget& grid,
                                    double noise_px, std::mt19937& rng) {
  ViewObservations view;
  view.image_width = camera.width_px;
  view.image_height = camera.height_px;
  std::normal_distribution<double> noise(0.0, 1.0);
  const double angle = pose.angle_axis.norm();
  const Eigen::Matrix3d r =
      angle > 0 ? Eigen::AngleAxisd(angle, pose.angle_axis / angle).toRotationMatrix() : Eigen::Matrix3d::Identity();
  for (int row = 0; row < grid.rows; ++row) {
    for (int col = 0; col < grid.cols; ++col) {
      CornerObservation c;
      c.id = row * grid.cols + col;
      c.target_mm = {col * grid.spacing_mm, row * grid.spacing_mm, 0.0};
      const Eigen::Vector3d in_cam = r * c.target_mm + pose.translation_mm;
      c.image_px = camera.Project(in_cam);
      if (noise_px > 0) c.image_px += noise_px * Eigen::Vector2d(noise(rng), noise(rng));
      if (c.image_px.x() < 0 || c.image_px.y() < 0 || c.image_px.x() > camera.width_px - 1 ||
          c.image_px.y() > camera.height_px - 1) {
        continue;
      }
      view.corners.push_back(c);
    }
  }
  return view;
}

// A 640x480 camera with OpenCV-like distortion and a spread of 8 target poses at ~450 mm.
inline model::CameraModel ReferenceCamera() {
  model::CameraModel cam;
  cam.width_px = 640;
  cam.height_px = 480;
  cam.fx_px = 540.0;
  cam.fy_px = 545.0;
  cam.cx_px = 322.5;
  cam.cy_px = 236.0;
  cam.dist = {-0.25, 0.08, 1.2e-3, -8e-4, -0.02};
  return cam;
}

inline std::vector<ViewPose> ReferencePoses(const GridTarget& grid) {
  return {MakePose(20, 0, 0, {0, 0, 450}, grid),     MakePose(-20, 5, 3, {10, 0, 470}, grid),
          MakePose(0, 25, -4, {-20, 10, 460}, grid), MakePose(5, -25, 8, {15, -10, 440}, grid),
          MakePose(15, 15, 0, {0, 5, 500}, grid),    MakePose(-15, -15, -10, {-10, 0, 420}, grid),
          MakePose(25, -10, 12, {30, 20, 520}, grid), MakePose(-10, 20, -6, {-30, -20, 480}, grid)};
}

}  // namespace topocal::calib::testing

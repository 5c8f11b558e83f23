#include "calib/calibrate.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <opencv2/calib3d.hpp>

#include "calib/calibrate_solve.h"

namespace topocal::calib {
namespace {

using internal::Failure;
using internal::FreeMask;
using internal::Parameters;
using internal::SolveAndReport;
using internal::UsedView;
using enum internal::ParamIndex;

FreeMask ComputeFreeMask(const CalibrationOptions& o, bool single_view) {
  const auto names = CameraParameterNames(o.model);
  FreeMask free(names.size(), true);
  for (size_t i = 0; i < names.size(); ++i) {
    if (o.fixed.count(names[i])) free[i] = false;
  }
  const int centre = internal::CentreIndex(o.model.lens);
  // Seidel: k1 alone of the lens model.
  if (o.model.seidel) std::fill(free.begin() + kDist + 1, free.begin() + centre, false);
  if (!o.fit_distortion_centre) free[static_cast<size_t>(centre)] = free[static_cast<size_t>(centre) + 1] = false;
  if (single_view) free[kFx] = free[kFy] = free[kCx] = free[kCy] = false;
  return free;
}

// Checks that the target points are planar (z = 0) and span two dimensions.
std::string CheckTargetLayout(const ViewObservations& view) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& c : view.corners) {
    if (std::abs(c.target_mm.z()) > 0) return fmt::format("corner {} is off the target plane (z = {} mm)", c.id, c.target_mm.z());
    mean += c.target_mm.head<2>();
  }
  mean /= static_cast<double>(view.corners.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& c : view.corners) {
    const Eigen::Vector2d d = c.target_mm.head<2>() - mean;
    scatter += d * d.transpose();
  }
  const Eigen::Vector2d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(scatter).eigenvalues();
  // Collinear corners leave the second eigenvalue at rounding level relative to the first.
  if (!(ev(0) > 1e-9 * ev(1))) return "the corners are collinear";
  return {};
}

std::array<double, kNumPose> ToArray(const ViewPose& pose) {
  return {pose.angle_axis.x(),     pose.angle_axis.y(),     pose.angle_axis.z(),
          pose.translation_mm.x(), pose.translation_mm.y(), pose.translation_mm.z()};
}

// The views a multi-view fit can use (enough corners, a planar two-dimensional target, the first usable view's image
// size), their indices, and the others in result->skipped_views. False with the failure in result.
bool SelectUsableViews(const std::vector<ViewObservations>& views, const CalibrationOptions& options,
                       CalibrationResult* result, std::vector<ViewObservations>* usable,
                       std::vector<int>* usable_index) {
  for (size_t i = 0; i < views.size(); ++i) {
    const auto& v = views[i];
    const int idx = static_cast<int>(i);
    if (static_cast<int>(v.corners.size()) < options.min_corners_per_view) {
      result->skipped_views.push_back(
          {idx, fmt::format("{} corners, fewer than {}", v.corners.size(), options.min_corners_per_view)});
      continue;
    }
    if (const auto layout = CheckTargetLayout(v); !layout.empty()) {
      if (layout.find("off the target plane") != std::string::npos) {
        *result = Failure(CalibrationStatus::kInvalidInput, fmt::format("view {} ({}): {}", i, v.image_path, layout));
        return false;
      }
      result->skipped_views.push_back({idx, layout});
      continue;
    }
    if (!usable->empty() &&
        (v.image_width != usable->front().image_width || v.image_height != usable->front().image_height)) {
      *result = Failure(CalibrationStatus::kInvalidInput,
                        fmt::format("view {} ({}) is {}x{} px, the first is {}x{} px", i, v.image_path, v.image_width,
                                    v.image_height, usable->front().image_width, usable->front().image_height));
      return false;
    }
    usable->push_back(v);
    usable_index->push_back(idx);
  }
  return true;
}

// The multi-view fit's start: Zhang's intrinsics (on the fixed aspect ratio when there is one), the board warp's
// frame, and Zhang's poses refined for the initial K.
Parameters InitialMultiViewParameters(const ZhangInitialisation& init, const std::vector<ViewObservations>& usable,
                                      const CalibrationOptions& options) {
  Parameters p;
  p.intrinsics = {init.fx_px, init.fy_px, init.cx_px, init.cy_px};
  if (options.fixed_aspect_ratio > 0) {
    // Start on the constraint with Zhang's geometric-mean focal length.
    const double f = std::sqrt(init.fx_px * init.fy_px);
    p.intrinsics[0] = f * std::sqrt(options.fixed_aspect_ratio);
    p.intrinsics[1] = f / std::sqrt(options.fixed_aspect_ratio);
  }
  if (options.fit_board_warp) {
    // The warp's frame: the bounding box of every corner seen (the printed pattern as far as the views know it).
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(INFINITY), hi = Eigen::Vector2d::Constant(-INFINITY);
    for (const auto& v : usable) {
      for (const auto& c : v.corners) {
        lo = lo.cwiseMin(c.target_mm.head<2>());
        hi = hi.cwiseMax(c.target_mm.head<2>());
      }
    }
    p.warp_geometry.centre_mm = 0.5 * (lo + hi);
    p.warp_geometry.half_size_mm = 0.5 * (hi - lo);
  }
  for (const auto& pose : init.cam_from_target) p.poses.push_back(ToArray(pose));
  // Refine each pose for the initial K (Zhang's rotation projection is only least-squares in the algebraic sense).
  const cv::Matx33d k(p.intrinsics[0], 0, p.intrinsics[2], 0, p.intrinsics[1], p.intrinsics[3], 0, 0, 1);
  for (size_t v = 0; v < usable.size(); ++v) {
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (const auto& c : usable[v].corners) {
      object.emplace_back(c.target_mm.x(), c.target_mm.y(), 0.0);
      image.emplace_back(c.image_px.x(), c.image_px.y());
    }
    cv::Vec3d rvec(p.poses[v][0], p.poses[v][1], p.poses[v][2]), tvec(p.poses[v][3], p.poses[v][4], p.poses[v][5]);
    if (cv::solvePnP(object, image, k, cv::noArray(), rvec, tvec, true, cv::SOLVEPNP_ITERATIVE) && tvec[2] > 0) {
      p.poses[v] = {rvec[0], rvec[1], rvec[2], tvec[0], tvec[1], tvec[2]};
    }
  }
  return p;
}

// What a single-view fit needs: the focal distance, pixel pitch and target distance, the image size, enough corners
// and a planar two-dimensional target; no board warp and no fixed aspect ratio. False with the failure in result.
bool CheckSingleView(const ViewObservations& view, const CalibrationOptions& options, CalibrationResult* result) {
  if (options.fit_board_warp) {
    *result = Failure(CalibrationStatus::kInvalidOptions,
                      "a board warp needs several views (one view cannot tell a warp from distortion)");
    return false;
  }
  if (options.fixed_aspect_ratio > 0) {
    *result = Failure(CalibrationStatus::kInvalidOptions,
                      "a fixed aspect ratio applies to multi-view fits (a single view holds fx = fy from the focal "
                      "distance and the pixel pitch)");
    return false;
  }
  if (!(options.focal_mm > 0 && options.pixel_pitch_um > 0 && options.distance_mm > 0)) {
    *result = Failure(CalibrationStatus::kInvalidOptions,
                      "single-view calibration needs the focal distance (mm), the pixel pitch (um) and the nominal "
                      "target distance (mm)");
    return false;
  }
  if (view.image_width <= 0 || view.image_height <= 0) {
    *result = Failure(CalibrationStatus::kInvalidInput, fmt::format("{}: image size unknown", view.image_path));
    return false;
  }
  if (static_cast<int>(view.corners.size()) < options.min_corners_per_view) {
    *result = Failure(CalibrationStatus::kTooFewCorners,
                      fmt::format("{}: {} corners, fewer than {}", view.image_path, view.corners.size(),
                                  options.min_corners_per_view));
    return false;
  }
  if (const auto layout = CheckTargetLayout(view); !layout.empty()) {
    *result = Failure(CalibrationStatus::kDegenerate, fmt::format("{}: {}", view.image_path, layout));
    return false;
  }
  return true;
}

// Pose: planar PnP (IPPE) with zero distortion, and an iterative PnP started fronto-parallel at the nominal
// distance with the target centroid on the axis; the one with the smaller reprojection error wins.
std::array<double, kNumPose> InitialSingleViewPose(const ViewObservations& view, const CalibrationOptions& options,
                                                   const Parameters& p, double f_px) {
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& c : view.corners) {
    object.emplace_back(c.target_mm.x(), c.target_mm.y(), 0.0);
    image.emplace_back(c.image_px.x(), c.image_px.y());
    centroid += c.target_mm;
  }
  centroid /= static_cast<double>(view.corners.size());
  const cv::Matx33d k(f_px, 0, p.intrinsics[2], 0, f_px, p.intrinsics[3], 0, 0, 1);
  const auto reprojection = [&](const cv::Vec3d& rvec, const cv::Vec3d& tvec) {
    std::vector<cv::Point2d> projected;
    cv::projectPoints(object, rvec, tvec, k, cv::noArray(), projected);
    double ssr = 0;
    for (size_t i = 0; i < projected.size(); ++i) {
      const cv::Point2d d = projected[i] - image[i];
      ssr += d.dot(d);
    }
    return std::isfinite(ssr) && tvec[2] > 0 ? ssr : INFINITY;
  };
  cv::Vec3d best_r(0, 0, 0), best_t(-centroid.x(), -centroid.y(), options.distance_mm);
  double best = reprojection(best_r, best_t);
  {
    cv::Vec3d r = best_r, t = best_t;
    if (cv::solvePnP(object, image, k, cv::noArray(), r, t, true, cv::SOLVEPNP_ITERATIVE) && reprojection(r, t) < best) {
      best = reprojection(r, t);
      best_r = r;
      best_t = t;
    }
    if (cv::solvePnP(object, image, k, cv::noArray(), r, t, false, cv::SOLVEPNP_IPPE) && reprojection(r, t) < best) {
      best = reprojection(r, t);
      best_r = r;
      best_t = t;
    }
  }
  return {best_r[0], best_r[1], best_r[2], best_t[0], best_t[1], best_t[2]};
}

}  // namespace

bool CalibrationOptions::IsValid(std::string* why) const {
  const auto fail = [why](std::string reason) {
    if (why) *why = std::move(reason);
    return false;
  };
  const auto names = CameraParameterNames(model);
  for (const auto& name : fixed) {
    if (std::find(names.begin(), names.end(), name) == names.end()) {
      return fail(fmt::format("unknown parameter '{}' to fix for model {} (one of {})", name, ToString(model),
                              fmt::join(names, ", ")));
    }
  }
  if (fit_distortion_centre && !model.seidel && !std::holds_alternative<model::BrownConrady>(model.lens)) {
    return fail(fmt::format("a distortion centre is fitted with seidel or brown5, not {}: its OpenCV equivalent is "
                            "found for those only",
                            ToString(model)));
  }
  if (fit_distortion_centre && !model.seidel && !(fixed.count("p1") && fixed.count("p2"))) {
    return fail("a free distortion centre and free p1, p2 are the same distortion to second order: fix p1,p2 or "
                "the centre");
  }
  if (!std::isfinite(fixed_aspect_ratio) || fixed_aspect_ratio < 0 ||
      (fixed_aspect_ratio > 0 && (fixed_aspect_ratio < 0.5 || fixed_aspect_ratio > 2))) {
    return fail(fmt::format("fixed aspect ratio fx / fy = {} is not a camera's (0 = free, else within [0.5, 2])",
                            fixed_aspect_ratio));
  }
  if (fixed_aspect_ratio > 0 && (fixed.count("fx") || fixed.count("fy"))) {
    return fail("a fixed aspect ratio ties fx and fy: fix neither, or fix both without the ratio");
  }
  if (!(loss_scale_px > 0)) return fail("loss scale must be > 0 px");
  if (!(outlier_threshold > 1)) return fail("outlier threshold must be > 1 robust sigma");
  if (max_outlier_rounds < 0) return fail("max outlier rounds must be >= 0");
  if (min_views < 2) return fail("min views must be >= 2");
  if (min_corners_per_view < 4) return fail("min corners per view must be >= 4");
  if (max_iterations < 1) return fail("max iterations must be >= 1");
  // Finite, and finite in pixels too: --focal-mm inf (or a pitch of 1e-300 um) reached Ceres as an Inf parameter.
  if (!(std::isfinite(focal_mm) && std::isfinite(pixel_pitch_um) && std::isfinite(distance_mm)) || focal_mm < 0 ||
      pixel_pitch_um < 0 || distance_mm < 0) {
    return fail("focal, pitch and distance must be finite and >= 0");
  }
  if (focal_mm > 0 && pixel_pitch_um > 0 && !std::isfinite(focal_mm / (pixel_pitch_um * 1e-3))) {
    return fail("focal / pixel pitch is not a finite focal length in pixels");
  }
  if (!(magnification != 0) || !std::isfinite(magnification)) return fail("magnification M_T must be non-zero");
  return true;
}

CalibrationResult CalibrateMultiView(const std::vector<ViewObservations>& views, const CalibrationOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Failure(CalibrationStatus::kInvalidOptions, why);
  CalibrationResult result;
  result.model = options.model;
  std::vector<ViewObservations> usable;
  std::vector<int> usable_index;
  if (!SelectUsableViews(views, options, &result, &usable, &usable_index)) return result;
  if (static_cast<int>(usable.size()) < options.min_views) {
    auto f = Failure(CalibrationStatus::kTooFewViews,
                     fmt::format("{} usable views, at least {} needed", usable.size(), options.min_views));
    f.skipped_views = result.skipped_views;
    return f;
  }
  const ZhangInitialisation init = InitialiseZhang(usable);
  if (!init.ok) return Failure(CalibrationStatus::kDegenerate, init.message);
  Parameters p = InitialMultiViewParameters(init, usable, options);
  p.lens = options.model.lens;

  std::vector<UsedView> used;
  for (size_t v = 0; v < usable.size(); ++v) {
    used.push_back({usable_index[v], &usable[v], std::vector<bool>(usable[v].corners.size(), true)});
  }
  result.single_view = false;
  result.camera.width_px = usable.front().image_width;
  result.camera.height_px = usable.front().image_height;
  result.views_used = usable_index;
  auto skipped = result.skipped_views;
  auto out = SolveAndReport(p, used, ComputeFreeMask(options, false), options, std::move(result));
  if (!out.ok()) out.skipped_views = skipped;
  out.model = options.model;
  return out;
}

CalibrationResult CalibrateSingleView(const ViewObservations& view, const CalibrationOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Failure(CalibrationStatus::kInvalidOptions, why);
  if (CalibrationResult failure; !CheckSingleView(view, options, &failure)) return failure;
  Parameters p;
  p.lens = options.model.lens;
  const double f_px = options.focal_mm / (options.pixel_pitch_um * 1e-3);
  p.intrinsics = {f_px, f_px, 0.5 * (view.image_width - 1), 0.5 * (view.image_height - 1)};
  p.poses.push_back(InitialSingleViewPose(view, options, p, f_px));

  std::vector<UsedView> used{{0, &view, std::vector<bool>(view.corners.size(), true)}};
  CalibrationResult result;
  result.model = options.model;
  result.single_view = true;
  result.camera.width_px = view.image_width;
  result.camera.height_px = view.image_height;
  result.views_used = {0};
  auto out = SolveAndReport(p, used, ComputeFreeMask(options, true), options, std::move(result));
  out.model = options.model;
  out.single_view = true;
  return out;
}

}  // namespace topocal::calib

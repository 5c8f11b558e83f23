#include "calib/render_target.h"

#include <cmath>
#include <limits>
#include <random>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "calib/target_drawing.h"

namespace topocal::calib {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
// Largest supersampling accepted: 64 x 64 = 4096 samples per pixel is already a reference-quality render.
constexpr int kMaxSupersampling = 64;
// Newton steps per sub-sample from the bilinear guess. The guess is within ~1e-3 px of the exact inverse (second
// derivative of the distortion over one pixel); each step squares the relative error, two steps reach ~1e-9 px.
constexpr int kSubSampleNewtonSteps = 2;

// Inverse CDF of one pixel's response along one axis: a uniform pixel box [-1/2, 1/2] convolved with the optical
// Gaussian blur. CDF(x) = sigma (Psi((x + 1/2) / sigma) - Psi((x - 1/2) / sigma)), Psi(z) = z Phi(z) + phi(z)
// (the antiderivative of the normal CDF); tabulated by bisection and interpolated linearly.
class OffsetTable {
 public:
  explicit OffsetTable(double sigma_px) : sigma_(sigma_px) {
    if (sigma_ <= 0) return;
    table_.resize(kEntries + 1);
    for (int i = 0; i <= kEntries; ++i) {
      // Probabilities clipped at the 4-sigma tails: samples beyond carry < 1e-4 of the weight.
      const double p = std::clamp(static_cast<double>(i) / kEntries, kTail, 1.0 - kTail);
      double lo = -0.5 - 8 * sigma_, hi = 0.5 + 8 * sigma_;
      for (int iteration = 0; iteration < 60; ++iteration) {
        const double mid = 0.5 * (lo + hi);
        (Cdf(mid) < p ? lo : hi) = mid;
      }
      table_[static_cast<size_t>(i)] = 0.5 * (lo + hi);
    }
  }
  // Offset from the pixel centre for a uniform p in [0, 1).
  double Offset(double p) const {
    if (sigma_ <= 0) return p - 0.5;
    const double f = p * kEntries;
    const int i = std::min(kEntries - 1, static_cast<int>(f));
    return table_[static_cast<size_t>(i)] + (f - i) * (table_[static_cast<size_t>(i + 1)] - table_[static_cast<size_t>(i)]);
  }
  double MaxOffset() const { return sigma_ <= 0 ? 0.5 : std::max(-table_.front(), table_.back()); }

 private:
  static constexpr int kEntries = 4096;
  static constexpr double kTail = 3.2e-5;  // Phi(-4)
  static double Psi(double z) { return z * 0.5 * std::erfc(-z / M_SQRT2) + std::exp(-0.5 * z * z) / std::sqrt(2 * M_PI); }
  double Cdf(double x) const { return sigma_ * (Psi((x + 0.5) / sigma_) - Psi((x - 0.5) / sigma_)); }

  double sigma_;
  std::vector<double> table_;
};

}  // namespace

CamFromTarget PoseFromRotationVector(const Eigen::Vector3d& rotation_vector_deg, const Eigen::Vector3d& translation_mm) {
  CamFromTarget pose;
  const double angle_rad = rotation_vector_deg.norm() * kDegToRad;
  if (angle_rad > 0) pose.rotation = Eigen::AngleAxisd(angle_rad, rotation_vector_deg.normalized()).toRotationMatrix();
  pose.translation_mm = translation_mm;
  return pose;
}

CamFromTarget PoseFacingTarget(const TargetDescription& target, double distance_mm, double tilt_x_deg,
                               double tilt_y_deg, double roll_deg, double shift_x_mm, double shift_y_mm) {
  const TargetExtent e = target.PatternExtent();
  const Eigen::Vector3d centre_mm(0.5 * (e.min_x_mm + e.max_x_mm), 0.5 * (e.min_y_mm + e.max_y_mm), 0.0);
  CamFromTarget pose;
  pose.rotation = (Eigen::AngleAxisd(roll_deg * kDegToRad, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(tilt_y_deg * kDegToRad, Eigen::Vector3d::UnitY()) *
                   Eigen::AngleAxisd(tilt_x_deg * kDegToRad, Eigen::Vector3d::UnitX()))
                      .toRotationMatrix();
  pose.translation_mm = Eigen::Vector3d(shift_x_mm, shift_y_mm, distance_mm) - pose.rotation * centre_mm;
  return pose;
}

cv::Mat AddSensorNoise(const cv::Mat& irradiance, double noise_grey, uint32_t seed) {
  cv::Mat image(irradiance.rows, irradiance.cols, CV_8UC1);
  // Its own stream (seed + 1), so that the same seed gives the same noise whether or not the sampling ran first.
  std::mt19937 rng(seed + 1);
  std::normal_distribution<double> noise(0.0, noise_grey > 0 ? noise_grey : 1.0);
  for (int y = 0; y < irradiance.rows; ++y) {
    const auto* in = irradiance.ptr<float>(y);
    auto* out = image.ptr<uint8_t>(y);
    for (int x = 0; x < irradiance.cols; ++x) {
      const double value = in[x] + (noise_grey > 0 ? noise(rng) : 0.0);
      out[x] = static_cast<uint8_t>(std::clamp(std::lround(value), 0L, 255L));
    }
  }
  return image;
}

bool RenderOptions::IsValid(std::string* why) const {
  auto fail = [&](std::string message) {
    if (why) *why = std::move(message);
    return false;
  };
  if (supersampling < 1 || supersampling > kMaxSupersampling) {
    return fail(fmt::format("supersampling must be 1..{}, got {}", kMaxSupersampling, supersampling));
  }
  if (!std::isfinite(blur_sigma_px) || blur_sigma_px < 0) return fail("blur sigma must be >= 0 px");
  if (!std::isfinite(noise_grey) || noise_grey < 0) return fail("noise must be >= 0 grey levels");
  for (double g : {black_grey, white_grey, background_grey}) {
    if (!std::isfinite(g) || g < 0 || g > 255) return fail("grey levels must lie in 0..255");
  }
  return true;
}

std::optional<RenderedView> RenderTarget(const TargetDescription& target, const model::CameraModel& camera,
                                         const CamFromTarget& pose, const RenderOptions& options, std::string* why) {
  if (!options.IsValid(why)) return std::nullopt;
  const int width = camera.width_px, height = camera.height_px;
  if (width < 1 || height < 1 || width > 20000 || height > 20000 || !(camera.fx_px > 0) || !(camera.fy_px > 0)) {
    if (why) *why = fmt::format("camera needs 1..20000 px sides and positive focal lengths");
    return std::nullopt;
  }
  const TargetPattern pattern(target);

  // Exact undistorted rays at the pixel-corner lattice (x - 0.5, y - 0.5), x = 0..width, y = 0..height.
  const int lw = width + 1, lh = height + 1;
  std::vector<Eigen::Vector2d> lattice(static_cast<size_t>(lw * lh));
  std::vector<uint8_t> lattice_ok(static_cast<size_t>(lw * lh));
  for (int y = 0; y < lh; ++y) {
    for (int x = 0; x < lw; ++x) {
      const auto u = camera.PixelToNormalized(Eigen::Vector2d(x - 0.5, y - 0.5));
      lattice_ok[static_cast<size_t>(y * lw + x)] = u.has_value();
      if (u) lattice[static_cast<size_t>(y * lw + x)] = *u;
    }
  }

  // Ray (u, 1) meets the plane where [r1 r2 t] (x, y, 1)^T is proportional to (u, 1).
  Eigen::Matrix3d plane_to_ray;
  plane_to_ray << pose.rotation.col(0), pose.rotation.col(1), pose.translation_mm;
  const Eigen::Matrix3d ray_to_plane = plane_to_ray.inverse();
  const double intrinsics[4] = {camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px};

  // Fibonacci lattice with F_k ~ N^2 points (i / F_k, frac(i F_{k-1} / F_k)): a rank-1 lattice whose x and y
  // projections are both all F_k multiples of 1 / F_k and whose 2-D spacing is near-uniform in every direction, so
  // edges of any orientation are sampled evenly (a sheared N x N grid is evenly spread only near the axes).
  int fib_prev = 1, fib = 2;
  while (fib + fib_prev <= options.supersampling * options.supersampling ||
         std::abs(fib + fib_prev - options.supersampling * options.supersampling) <
             std::abs(fib - options.supersampling * options.supersampling)) {
    const int next = fib + fib_prev;
    fib_prev = fib;
    fib = next;
  }
  const int samples = options.supersampling == 1 ? 1 : fib;
  std::vector<Eigen::Vector2d> base(static_cast<size_t>(samples));
  for (int i = 0; i < samples; ++i) {
    const double y = (static_cast<double>(i) * fib_prev + 0.5) / samples;
    base[static_cast<size_t>(i)] = Eigen::Vector2d((i + 0.5) / samples, y - std::floor(y));
  }
  // Each stratified uniform coordinate goes through the inverse CDF of (pixel box + optical Gaussian blur), per
  // axis: the sample then follows the pixel's response to a point of the scene, blur included.
  const OffsetTable offsets(options.blur_sigma_px);
  const double ink = options.black_grey, paper = options.white_grey, background = options.background_grey;
  auto grey_of_ray = [&](const Eigen::Vector2d& u) {
    const Eigen::Vector3d q = ray_to_plane * Eigen::Vector3d(u.x(), u.y(), 1.0);
    if (!(q.z() > 0)) return background;  // the ray meets the plane behind the camera, or runs parallel to it
    const double x_mm = q.x() / q.z(), y_mm = q.y() / q.z();
    return !pattern.OnPaper(x_mm, y_mm) ? background : pattern.IsBlack(x_mm, y_mm) ? ink : paper;
  };
  // Grey at every lattice point (a sentinel where the inverse failed). A pixel all of whose response support
  // (half a pixel + 4 blur sigmas, plus one lattice step) sees one grey at every lattice point lies inside a
  // uniform region — provided every printed feature is wider than a pixel in the image — and is set without
  // sub-sampling. Only pixels near an edge are sub-sampled, which makes dense sub-sampling affordable.
  constexpr float kInvalidGrey = -1000.0f;
  cv::Mat lattice_grey(lh, lw, CV_32FC1);
  for (int y = 0; y < lh; ++y) {
    for (int x = 0; x < lw; ++x) {
      const size_t i = static_cast<size_t>(y * lw + x);
      lattice_grey.at<float>(y, x) = lattice_ok[i] ? static_cast<float>(grey_of_ray(lattice[i])) : kInvalidGrey;
    }
  }
  const int reach = static_cast<int>(std::ceil(offsets.MaxOffset())) + 1;
  const cv::Mat kernel = cv::Mat::ones(2 * reach + 1, 2 * reach + 1, CV_8U);
  cv::Mat lattice_min, lattice_max;
  cv::erode(lattice_grey, lattice_min, kernel, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  cv::dilate(lattice_grey, lattice_max, kernel, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);

  std::mt19937 rng(options.seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);

  cv::Mat irradiance(height, width, CV_32FC1);
  for (int y = 0; y < height; ++y) {
    auto* row = irradiance.ptr<float>(y);
    for (int x = 0; x < width; ++x) {
      const Eigen::Vector2d shift(uniform(rng), uniform(rng));
      const float lo = lattice_min.at<float>(y, x), hi = lattice_max.at<float>(y, x);
      if (lo == hi && lo != kInvalidGrey) {
        row[x] = lo;
        continue;
      }
      double sum = 0;
      for (int k = 0; k < samples; ++k) {
        Eigen::Vector2d st = base[static_cast<size_t>(k)] + shift;
        const Eigen::Vector2d target_px(x + offsets.Offset(st.x() - std::floor(st.x())),
                                        y + offsets.Offset(st.y() - std::floor(st.y())));
        // The lattice cell holding the sample (clamped at the image border, where Newton extrapolates).
        const int cx = std::clamp(static_cast<int>(std::floor(target_px.x() + 0.5)), 0, width - 1);
        const int cy = std::clamp(static_cast<int>(std::floor(target_px.y() + 0.5)), 0, height - 1);
        const size_t i00 = static_cast<size_t>(cy * lw + cx), i10 = i00 + 1, i01 = i00 + static_cast<size_t>(lw),
                     i11 = i01 + 1;
        if (!(lattice_ok[i00] && lattice_ok[i10] && lattice_ok[i01] && lattice_ok[i11])) {
          sum += background;
          continue;
        }
        const Eigen::Vector2d &u00 = lattice[i00], &u10 = lattice[i10], &u01 = lattice[i01], &u11 = lattice[i11];
        const double s = target_px.x() - (cx - 0.5), t = target_px.y() - (cy - 0.5);
        // Bilinear guess and the local Jacobian d(u)/d(px) of the lattice cell, then Newton on the forward model.
        Eigen::Vector2d u = (1 - t) * ((1 - s) * u00 + s * u10) + t * ((1 - s) * u01 + s * u11);
        Eigen::Matrix2d du_dpx;
        du_dpx.col(0) = (1 - t) * (u10 - u00) + t * (u11 - u01);
        du_dpx.col(1) = (1 - s) * (u01 - u00) + s * (u11 - u10);
        for (int step = 0; step < kSubSampleNewtonSteps; ++step) {
          Eigen::Vector2d px;
          model::CameraModel::NormalizedToPixel(intrinsics, camera.dist.data(), camera.distortion_centre.data(),
                                                u.data(), px.data());
          u += du_dpx * (target_px - px);
        }
        sum += grey_of_ray(u);
      }
      row[x] = static_cast<float>(sum / samples);
    }
  }

  RenderedView view;
  view.image = AddSensorNoise(irradiance, options.noise_grey, options.seed);
  view.irradiance = irradiance;

  for (int id : target.CornerIds()) {
    const Eigen::Vector3d in_cam = pose.rotation * *target.CornerMm(id) + pose.translation_mm;
    if (!(in_cam.z() > 0)) continue;
    const Eigen::Vector2d px = camera.Project(in_cam);
    if (!(px.x() >= 0 && px.y() >= 0 && px.x() <= width - 1 && px.y() <= height - 1)) continue;
    // Beyond the fold of strong distortion Project is not invertible: such a corner is not where it seems (the
    // inverse lands on the other branch, pixels or more away). The bar is far above the inverse's own tolerance
    // (1e-6 px): at 1e-6 px itself, converged corners were dropped from the truth at random.
    constexpr double kFoldDetectionPx = 1e-3;
    const auto back = camera.PixelToNormalized(px);
    if (!back || (*back - in_cam.head<2>() / in_cam.z()).norm() * camera.fx_px > kFoldDetectionPx) continue;
    view.corners.push_back({id, px});
  }
  return view;
}

std::string CornerTruthCsv(const RenderedView& view) {
  std::string csv = "id,x_px,y_px\n";
  for (const auto& c : view.corners) csv += fmt::format("{},{:.9f},{:.9f}\n", c.id, c.image_px.x(), c.image_px.y());
  return csv;
}

}  // namespace topocal::calib

#include "calib/render_target.h"

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <limits>
#include <mutex>
#include <random>
#include <thread>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "calib/target_drawing.h"
#include "util/parallel.h"

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

// Grey of a lattice point whose inverse failed: below every grey, so that the window minimum shows it.
constexpr float kInvalidGrey = -1000.0f;
// Rows of pixels per work item: enough to amortise the engine copy (5 KB), few enough to balance two cores.
constexpr int kRowsPerItem = 16;

// Fibonacci lattice with F_k ~ N^2 points (i / F_k, frac(i F_{k-1} / F_k)): a rank-1 lattice whose x and y
// projections are both all F_k multiples of 1 / F_k and whose 2-D spacing is near-uniform in every direction, so
// edges of any orientation are sampled evenly (a sheared N x N grid is evenly spread only near the axes).
std::vector<Eigen::Vector2d> FibonacciLattice(int supersampling) {
  const int n2 = supersampling * supersampling;
  int fib_prev = 1, fib = 2;
  while (fib + fib_prev <= n2 || std::abs(fib + fib_prev - n2) < std::abs(fib - n2)) {
    const int next = fib + fib_prev;
    fib_prev = fib;
    fib = next;
  }
  const int samples = supersampling == 1 ? 1 : fib;
  std::vector<Eigen::Vector2d> base(static_cast<size_t>(samples));
  for (int i = 0; i < samples; ++i) {
    const double y = (static_cast<double>(i) * fib_prev + 0.5) / samples;
    base[static_cast<size_t>(i)] = Eigen::Vector2d((i + 0.5) / samples, y - std::floor(y));
  }
  return base;
}

// std::uniform_real_distribution<double>(0, 1) on mt19937 as libstdc++ computes it (generate_canonical: two 32-bit
// outputs, low word first), spelled out so that a draw costs exactly two engine outputs by this code's definition:
// rows rendered in parallel position their engine by that count.
double Canonical(std::mt19937& engine) {
  const double low = static_cast<double>(engine());
  const double high = static_cast<double>(engine());
  const double u = (low + high * 4294967296.0) / 18446744073709551616.0;
  return u < 1.0 ? u : std::nextafter(1.0, 0.0);
}
constexpr unsigned long long kEngineOutputsPerPixel = 4;  // the pixel's two shift coordinates

// What a ray sees: the grey of the ink, paper or background where it meets the target plane.
struct Scene {
  const TargetPattern& pattern;
  Eigen::Matrix3d ray_to_plane;  // ray (u, 1) -> homogeneous target-plane point
  double ink, paper, background;

  double GreyOfRay(const Eigen::Vector2d& u) const {
    const Eigen::Vector3d q = ray_to_plane * Eigen::Vector3d(u.x(), u.y(), 1.0);
    if (!(q.z() > 0)) return background;  // the ray meets the plane behind the camera, or runs parallel to it
    const double x_mm = q.x() / q.z(), y_mm = q.y() / q.z();
    return !pattern.OnPaper(x_mm, y_mm) ? background : pattern.IsBlack(x_mm, y_mm) ? ink : paper;
  }
};

// The pixel-corner lattice points (index i sits at pixel coordinate i - 1/2) whose ray can meet the paper: the
// paper's image through the forward model, every branch of it (the per-point inverse may converge on any),
// widened by `margin_px`. Elsewhere every ray sees the background or has no inverse, and a pixel whose whole
// support lies there renders as the background either way — so only this footprint needs the inverse.
struct Footprint {
  cv::Rect rect;  // lattice points covered, within the lattice; empty when the paper is out of view
  cv::Mat mask;   // CV_8U over rect: 1 where a ray may meet the paper
};

// Bounds the paper's image cell by cell: each cell by the box of 3 x 3 projected points widened by twice their
// largest departure from the bilinear interpolation of the corners (the map's curvature over the cell), cells split
// until that departure is under kMaxBulgePx and the box under kMaxCellPx. Fails (the caller then inverts every
// point) when the paper reaches the camera's plane or the splitting does not settle.
class FootprintBuilder {
 public:
  FootprintBuilder(const model::CameraModel& camera, const CamFromTarget& pose, double margin_px)
      : camera_(camera), pose_(pose), margin_px_(margin_px) {}

  std::optional<Footprint> Build(const TargetExtent& paper) {
    for (double x : {paper.min_x_mm, paper.max_x_mm}) {
      for (double y : {paper.min_y_mm, paper.max_y_mm}) {
        // z is affine on the plane: positive at the four corners, positive over the whole (convex) paper.
        if (!((pose_.rotation * Eigen::Vector3d(x, y, 0) + pose_.translation_mm).z() > 0)) return std::nullopt;
      }
    }
    if (!AddCell(paper.min_x_mm, paper.min_y_mm, paper.max_x_mm, paper.max_y_mm, 0)) return std::nullopt;
    Footprint footprint;
    for (const cv::Rect& box : boxes_) footprint.rect |= box;
    footprint.mask = cv::Mat::zeros(footprint.rect.size(), CV_8U);
    for (const cv::Rect& box : boxes_) footprint.mask(box - footprint.rect.tl()).setTo(1);
    return footprint;
  }

 private:
  static constexpr double kMaxBulgePx = 0.25;
  static constexpr double kMaxCellPx = 32.0;
  static constexpr int kMaxDepth = 24;
  static constexpr size_t kMaxCells = size_t{1} << 18;

  bool AddCell(double x0_mm, double y0_mm, double x1_mm, double y1_mm, int depth) {
    if (++cells_ > kMaxCells) return false;
    Eigen::Vector2d p[3][3];
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (int j = 0; j < 3; ++j) {
      for (int i = 0; i < 3; ++i) {
        const Eigen::Vector3d in_target(x0_mm + 0.5 * i * (x1_mm - x0_mm), y0_mm + 0.5 * j * (y1_mm - y0_mm), 0.0);
        p[j][i] = camera_.Project(pose_.rotation * in_target + pose_.translation_mm);
        if (!p[j][i].allFinite()) return false;
        lo = lo.cwiseMin(p[j][i]);
        hi = hi.cwiseMax(p[j][i]);
      }
    }
    const double bulge_px = std::max({(p[0][1] - 0.5 * (p[0][0] + p[0][2])).norm(),
                                      (p[2][1] - 0.5 * (p[2][0] + p[2][2])).norm(),
                                      (p[1][0] - 0.5 * (p[0][0] + p[2][0])).norm(),
                                      (p[1][2] - 0.5 * (p[0][2] + p[2][2])).norm(),
                                      (p[1][1] - 0.25 * (p[0][0] + p[0][2] + p[2][0] + p[2][2])).norm()});
    const double widen_px = 2.0 * bulge_px + margin_px_;
    // Lattice index = pixel coordinate + 1/2; the lattice spans indices 0 .. width, 0 .. height.
    const double i_lo = lo.x() + 0.5 - widen_px, i_hi = hi.x() + 0.5 + widen_px;
    const double j_lo = lo.y() + 0.5 - widen_px, j_hi = hi.y() + 0.5 + widen_px;
    if (i_hi < 0 || j_hi < 0 || i_lo > camera_.width_px || j_lo > camera_.height_px) return true;  // out of view
    if (bulge_px > kMaxBulgePx || (hi - lo).maxCoeff() > kMaxCellPx) {
      if (depth == kMaxDepth) return false;
      const double xm_mm = 0.5 * (x0_mm + x1_mm), ym_mm = 0.5 * (y0_mm + y1_mm);
      return AddCell(x0_mm, y0_mm, xm_mm, ym_mm, depth + 1) && AddCell(xm_mm, y0_mm, x1_mm, ym_mm, depth + 1) &&
             AddCell(x0_mm, ym_mm, xm_mm, y1_mm, depth + 1) && AddCell(xm_mm, ym_mm, x1_mm, y1_mm, depth + 1);
    }
    const int a = std::max(0, static_cast<int>(std::floor(i_lo))), b = std::max(0, static_cast<int>(std::floor(j_lo)));
    const int c = std::min(camera_.width_px, static_cast<int>(std::ceil(i_hi)));
    const int d = std::min(camera_.height_px, static_cast<int>(std::ceil(j_hi)));
    boxes_.emplace_back(a, b, c - a + 1, d - b + 1);
    return true;
  }

  const model::CameraModel& camera_;
  const CamFromTarget& pose_;
  double margin_px_;
  size_t cells_ = 0;
  std::vector<cv::Rect> boxes_;
};

// The exact undistorted rays and what they see at the lattice points of `rect` (the footprint widened by the
// pixels' reach): inverted where the footprint says a ray may meet the paper, the background elsewhere.
struct RayLattice {
  cv::Rect rect;
  std::vector<Eigen::Vector2d> rays;  // row-major over rect
  std::vector<uint8_t> ok;            // 1 where the ray is known: the inverse converged inside the footprint
  cv::Mat grey;                       // CV_32FC1 over rect; kInvalidGrey where the inverse failed

  bool Ok(int i, int j) const {
    return rect.contains(cv::Point(i, j)) && ok[static_cast<size_t>((j - rect.y) * rect.width + (i - rect.x))];
  }
  const Eigen::Vector2d& Ray(int i, int j) const {
    return rays[static_cast<size_t>((j - rect.y) * rect.width + (i - rect.x))];
  }
};

RayLattice InvertLattice(const model::CameraModel& camera, const Scene& scene, const Footprint& footprint, int reach,
                         int jobs) {
  RayLattice lattice;
  const cv::Rect all(0, 0, camera.width_px + 1, camera.height_px + 1);
  lattice.rect = cv::Rect(footprint.rect.x - reach, footprint.rect.y - reach, footprint.rect.width + 2 * reach,
                          footprint.rect.height + 2 * reach) & all;
  const cv::Rect& r = lattice.rect;
  lattice.rays.resize(static_cast<size_t>(r.area()));
  lattice.ok.assign(static_cast<size_t>(r.area()), 0);
  lattice.grey = cv::Mat(r.size(), CV_32FC1);
  const size_t items = static_cast<size_t>((r.height + kRowsPerItem - 1) / kRowsPerItem);
  util::ParallelFor(items, jobs, [&](size_t item) {
    const int j_end = std::min(r.y + r.height, r.y + (static_cast<int>(item) + 1) * kRowsPerItem);
    for (int j = r.y + static_cast<int>(item) * kRowsPerItem; j < j_end; ++j) {
      auto* grey = lattice.grey.ptr<float>(j - r.y);
      for (int i = r.x; i < r.x + r.width; ++i) {
        const size_t k = static_cast<size_t>((j - r.y) * r.width + (i - r.x));
        const cv::Point in_footprint = cv::Point(i, j) - footprint.rect.tl();
        if (!footprint.rect.contains(cv::Point(i, j)) || !footprint.mask.at<uint8_t>(in_footprint)) {
          grey[i - r.x] = static_cast<float>(scene.background);
          continue;
        }
        const auto u = camera.PixelToNormalized(Eigen::Vector2d(i - 0.5, j - 0.5));
        lattice.ok[k] = u.has_value();
        if (u) lattice.rays[k] = *u;
        grey[i - r.x] = u ? static_cast<float>(scene.GreyOfRay(*u)) : kInvalidGrey;
      }
    }
  });
  return lattice;
}

// Everything the pixels' sub-sampling reads, fixed for the whole image.
struct Sampler {
  const model::CameraModel& camera;
  const Scene& scene;
  const RayLattice& lattice;
  const OffsetTable& offsets;
  const std::vector<Eigen::Vector2d>& base;  // the Fibonacci lattice in [0, 1)^2

  // The mean grey over the pixel's sub-samples, shifted by `shift` (Cranley-Patterson rotation).
  double PixelGrey(int x, int y, const Eigen::Vector2d& shift) const {
    const double intrinsics[4] = {camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px};
    double sum = 0;
    for (const Eigen::Vector2d& b : base) {
      const Eigen::Vector2d st = b + shift;
      const Eigen::Vector2d target_px(x + offsets.Offset(st.x() - std::floor(st.x())),
                                      y + offsets.Offset(st.y() - std::floor(st.y())));
      // The lattice cell holding the sample (clamped at the image border, where Newton extrapolates).
      const int cx = std::clamp(static_cast<int>(std::floor(target_px.x() + 0.5)), 0, camera.width_px - 1);
      const int cy = std::clamp(static_cast<int>(std::floor(target_px.y() + 0.5)), 0, camera.height_px - 1);
      if (!(lattice.Ok(cx, cy) && lattice.Ok(cx + 1, cy) && lattice.Ok(cx, cy + 1) && lattice.Ok(cx + 1, cy + 1))) {
        sum += scene.background;
        continue;
      }
      const Eigen::Vector2d &u00 = lattice.Ray(cx, cy), &u10 = lattice.Ray(cx + 1, cy);
      const Eigen::Vector2d &u01 = lattice.Ray(cx, cy + 1), &u11 = lattice.Ray(cx + 1, cy + 1);
      const double s = target_px.x() - (cx - 0.5), t = target_px.y() - (cy - 0.5);
      // Bilinear guess and the local Jacobian d(u)/d(px) of the lattice cell, then Newton on the forward model.
      Eigen::Vector2d u = (1 - t) * ((1 - s) * u00 + s * u10) + t * ((1 - s) * u01 + s * u11);
      Eigen::Matrix2d du_dpx;
      du_dpx.col(0) = (1 - t) * (u10 - u00) + t * (u11 - u01);
      du_dpx.col(1) = (1 - s) * (u01 - u00) + s * (u11 - u10);
      for (int step = 0; step < kSubSampleNewtonSteps; ++step) {
        Eigen::Vector2d px;
        model::CameraModel::NormalizedToPixel(camera.lens, intrinsics, camera.dist.data(),
                                              camera.distortion_centre.data(), u.data(), px.data());
        u += du_dpx * (target_px - px);
      }
      sum += scene.GreyOfRay(u);
    }
    return sum / static_cast<double>(base.size());
  }
};

// Which row items of the irradiance are final, for the noise that follows them in raster order on its own thread.
class RowItemsDone {
 public:
  explicit RowItemsDone(size_t items) : done_(items, 0) {}
  void MarkDone(size_t item) {
    {
      const std::lock_guard lock(mutex_);
      done_[item] = 1;
    }
    changed_.notify_all();
  }
  void Abandon() {
    {
      const std::lock_guard lock(mutex_);
      abandoned_ = true;
    }
    changed_.notify_all();
  }
  // false when the rendering was abandoned (an exception on its way to the caller).
  bool WaitFor(size_t item) {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return abandoned_ || done_[item] != 0; });
    return !abandoned_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<uint8_t> done_;
  bool abandoned_ = false;
};

// The irradiance, kRowsPerItem rows per work item: the background where no pixel's support reaches the lattice,
// else each pixel's grey. Each pixel draws its shift from one seeded stream in raster order, 4 engine outputs per
// pixel of the image, so every row starts at a known position: an item copies the engine at its first row, and the
// image does not depend on the thread count. A pixel whose whole support (min == max over the window) sees one grey
// is not sub-sampled.
void SampleRows(const Sampler& sampler, const cv::Mat& window_min, const cv::Mat& window_max, uint32_t seed, int jobs,
                RowItemsDone& done, cv::Mat& irradiance) {
  const cv::Rect pixels = sampler.lattice.rect & cv::Rect(0, 0, irradiance.cols, irradiance.rows);
  const auto draw_at = [&](int x, int y) {
    return kEngineOutputsPerPixel * (static_cast<unsigned long long>(y) * irradiance.cols + x);
  };
  const size_t items = static_cast<size_t>((irradiance.rows + kRowsPerItem - 1) / kRowsPerItem);
  std::vector<std::mt19937> engines(items);
  std::mt19937 engine(seed);
  unsigned long long position = 0;
  for (size_t item = 0; item < items; ++item) {
    const int y0 = std::max(pixels.y, static_cast<int>(item) * kRowsPerItem);
    if (y0 >= std::min(pixels.y + pixels.height, static_cast<int>(item + 1) * kRowsPerItem)) continue;
    engine.discard(draw_at(0, y0) - position);
    position = draw_at(0, y0);
    engines[item] = engine;
  }
  const float background = static_cast<float>(sampler.scene.background);
  const cv::Point lattice_origin = sampler.lattice.rect.tl();
  util::ParallelFor(items, jobs, [&](size_t item) {
    std::mt19937& rng = engines[item];
    const int y_begin = static_cast<int>(item) * kRowsPerItem;
    unsigned long long at = draw_at(0, std::max(pixels.y, y_begin));
    for (int y = y_begin; y < std::min(y_begin + kRowsPerItem, irradiance.rows); ++y) {
      auto* row = irradiance.ptr<float>(y);
      if (y < pixels.y || y >= pixels.y + pixels.height) {
        std::fill(row, row + irradiance.cols, background);
        continue;
      }
      std::fill(row, row + pixels.x, background);
      std::fill(row + pixels.x + pixels.width, row + irradiance.cols, background);
      const auto* lo = window_min.ptr<float>(y - lattice_origin.y);
      const auto* hi = window_max.ptr<float>(y - lattice_origin.y);
      for (int x = pixels.x; x < pixels.x + pixels.width; ++x) {
        const float lo_grey = lo[x - lattice_origin.x], hi_grey = hi[x - lattice_origin.x];
        if (lo_grey == hi_grey && lo_grey != kInvalidGrey) {
          row[x] = lo_grey;
          continue;
        }
        rng.discard(draw_at(x, y) - at);
        at = draw_at(x, y) + kEngineOutputsPerPixel;
        // y before x: the stream's order for every seed since the first renders, so a seed keeps its image.
        const double shift_y = Canonical(rng);
        const double shift_x = Canonical(rng);
        row[x] = static_cast<float>(sampler.PixelGrey(x, y, Eigen::Vector2d(shift_x, shift_y)));
      }
    }
    done.MarkDone(item);
  });
}

// Seeded Gaussian noise (grey levels), rounded and clamped to 8 bits, row by row in raster order from one stream.
class SensorNoise {
 public:
  SensorNoise(double noise_grey, uint32_t seed)
      : noise_grey_(noise_grey), rng_(seed + 1), noise_(0.0, noise_grey > 0 ? noise_grey : 1.0) {}
  void Row(const float* in, uint8_t* out, int cols) {
    for (int x = 0; x < cols; ++x) {
      const double value = in[x] + (noise_grey_ > 0 ? noise_(rng_) : 0.0);
      out[x] = static_cast<uint8_t>(std::clamp(std::lround(value), 0L, 255L));
    }
  }

 private:
  double noise_grey_;
  // Its own stream (seed + 1), so that the same seed gives the same noise whether or not the sampling ran first.
  std::mt19937 rng_;
  std::normal_distribution<double> noise_;
};

// The irradiance and, behind it on a thread of its own, the noisy 8-bit image: the noise is one sequential stream
// (a normal deviate takes a varying number of engine outputs), so it follows the row items in order as they are
// finished instead of waiting for the whole irradiance.
cv::Mat SampleAndAddNoise(const Sampler& sampler, const cv::Mat& window_min, const cv::Mat& window_max,
                          const RenderOptions& options, cv::Mat& irradiance) {
  cv::Mat image(irradiance.rows, irradiance.cols, CV_8UC1);
  const size_t items = static_cast<size_t>((irradiance.rows + kRowsPerItem - 1) / kRowsPerItem);
  RowItemsDone done(items);
  const auto add_noise = [&] {
    SensorNoise noise(options.noise_grey, options.seed);
    for (size_t item = 0; item < items && done.WaitFor(item); ++item) {
      const int y_end = std::min(irradiance.rows, static_cast<int>(item + 1) * kRowsPerItem);
      for (int y = static_cast<int>(item) * kRowsPerItem; y < y_end; ++y) {
        noise.Row(irradiance.ptr<float>(y), image.ptr<uint8_t>(y), irradiance.cols);
      }
    }
  };
  const int jobs = options.jobs == 0 ? util::AvailableCores() : options.jobs;
  if (jobs == 1) {
    SampleRows(sampler, window_min, window_max, options.seed, 1, done, irradiance);
    add_noise();
    return image;
  }
  std::thread noise_thread(add_noise);
  try {
    SampleRows(sampler, window_min, window_max, options.seed, jobs, done, irradiance);
  } catch (...) {
    done.Abandon();
    noise_thread.join();
    throw;
  }
  noise_thread.join();
  return image;
}

// The truth: each corner projected, kept when it is in front of the camera, inside the image and not beyond the
// fold of strong distortion, where Project is not invertible and a corner is not where it seems (the inverse lands
// on the other branch, pixels or more away).
std::vector<CornerTruth> VisibleCorners(const TargetDescription& target, const model::CameraModel& camera,
                                        const CamFromTarget& pose) {
  std::vector<CornerTruth> corners;
  for (int id : target.CornerIds()) {
    const Eigen::Vector3d in_cam = pose.rotation * *target.CornerMm(id) + pose.translation_mm;
    if (!(in_cam.z() > 0)) continue;
    const Eigen::Vector2d px = camera.Project(in_cam);
    if (!(px.x() >= 0 && px.y() >= 0 && px.x() <= camera.width_px - 1 && px.y() <= camera.height_px - 1)) continue;
    // The bar is far above the inverse's own tolerance (1e-6 px): at 1e-6 px itself, converged corners were
    // dropped from the truth at random.
    constexpr double kFoldDetectionPx = 1e-3;
    const auto back = camera.PixelToNormalized(px);
    if (!back || (*back - in_cam.head<2>() / in_cam.z()).norm() * camera.fx_px > kFoldDetectionPx) continue;
    corners.push_back({id, px});
  }
  return corners;
}

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
  SensorNoise noise(noise_grey, seed);
  for (int y = 0; y < irradiance.rows; ++y) noise.Row(irradiance.ptr<float>(y), image.ptr<uint8_t>(y), irradiance.cols);
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
  if (jobs < 0) return fail("jobs must be >= 0 (0: every core)");
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
  // Ray (u, 1) meets the plane where [r1 r2 t] (x, y, 1)^T is proportional to (u, 1).
  Eigen::Matrix3d plane_to_ray;
  plane_to_ray << pose.rotation.col(0), pose.rotation.col(1), pose.translation_mm;
  const Scene scene{pattern, plane_to_ray.inverse(), options.black_grey, options.white_grey, options.background_grey};
  // Each stratified uniform coordinate goes through the inverse CDF of (pixel box + optical Gaussian blur), per
  // axis: the sample then follows the pixel's response to a point of the scene, blur included.
  const OffsetTable offsets(options.blur_sigma_px);
  const std::vector<Eigen::Vector2d> base = FibonacciLattice(options.supersampling);

  // A pixel all of whose response support (half a pixel + 4 blur sigmas, plus one lattice step: `reach` lattice
  // points either side) sees one grey at every lattice point lies inside a uniform region — provided every printed
  // feature is wider than a pixel in the image — and is set without sub-sampling. Only pixels near an edge are
  // sub-sampled, which makes dense sub-sampling affordable.
  const int reach = static_cast<int>(std::ceil(offsets.MaxOffset())) + 1;
  // The footprint's margin keeps every lattice point left out of it more than one window (2 reach) from the paper's
  // image, so that no window holds both such a point and a point that sees the paper.
  std::optional<Footprint> footprint = FootprintBuilder(camera, pose, 2 * reach + 2).Build(target.PaperExtent());
  if (!footprint) footprint = Footprint{cv::Rect(0, 0, width + 1, height + 1), cv::Mat::ones(height + 1, width + 1, CV_8U)};
  const RayLattice lattice = InvertLattice(camera, scene, *footprint, reach, options.jobs);
  const cv::Mat kernel = cv::Mat::ones(2 * reach + 1, 2 * reach + 1, CV_8U);
  cv::Mat window_min, window_max;
  cv::erode(lattice.grey, window_min, kernel, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  cv::dilate(lattice.grey, window_max, kernel, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);

  RenderedView view;
  view.irradiance = cv::Mat(height, width, CV_32FC1);
  view.image = SampleAndAddNoise(Sampler{camera, scene, lattice, offsets, base}, window_min, window_max, options,
                                 view.irradiance);
  view.corners = VisibleCorners(target, camera, pose);
  return view;
}

std::string CornerTruthCsv(const RenderedView& view) {
  std::string csv = "id,x_px,y_px\n";
  for (const auto& c : view.corners) csv += fmt::format("{},{:.9f},{:.9f}\n", c.id, c.image_px.x(), c.image_px.y());
  return csv;
}

}  // namespace topocal::calib

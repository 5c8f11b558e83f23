#include "correct/undistort_map.h"

#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <opencv2/imgproc.hpp>
#include "util/io.h"

namespace topocal::correct {
namespace {

// Output pixels where d r_d / d r has fallen below this are treated as beyond the fold: there one source pixel is
// smeared over more than 100 output pixels, nothing is left to recover, and the inverse is too ill-conditioned to
// check (a 1e-12 mm residual allows a 1e-10 mm error).
constexpr double kMinRadialDerivative = 0.01;

// Fills image rows [r0, r1) of the map with `distort` (mm -> mm), marking radii >= fold_radius_mm invalid; image
// row v goes to map row v - row_offset (a band of the map).
template <typename Distort>
void FillRows(const Distort& distort, const model::TopographerCamera& camera, const Eigen::Vector2d& centre_mm,
              double fold_radius_mm, int r0, int r1, cv::Mat* map_x, cv::Mat* map_y, int row_offset = 0) {
  // mm = M^T P (px - c) and px = c + P^-1 M mm, P = diag(pitch_u, pitch_v) (model/topographer_camera.h); M has
  // entries 0, +-1.
  const Eigen::Matrix2d m = camera.Orientation();
  const double pu = camera.PitchesMm().x(), pv = camera.PitchesMm().y();
  const double inv_u = 1.0 / pu, inv_v = 1.0 / pv;
  const double cu = camera.principal_point_px.x(), cv_ = camera.principal_point_px.y();
  const double fold2 = fold_radius_mm * fold_radius_mm;
  for (int v = r0; v < r1; ++v) {
    float* mx = map_x->ptr<float>(v - row_offset);
    float* my = map_y->ptr<float>(v - row_offset);
    const double dv = v - cv_;
    // Branch-free so that the compiler can vectorise the row: evaluate everywhere, then select.
    for (int u = 0; u < camera.width_px; ++u) {
      const double du = u - cu;
      const double x = m(0, 0) * pu * du + m(1, 0) * pv * dv;
      const double y = m(0, 1) * pu * du + m(1, 1) * pv * dv;
      const double dx = x - centre_mm.x(), dy = y - centre_mm.y();
      const double valid = dx * dx + dy * dy < fold2 ? 1.0 : 0.0;
      double out_x, out_y;
      distort(x, y, &out_x, &out_y);
      // Arithmetic select (exact: one term is multiplied by zero): no control flow in the loop body.
      mx[u] = static_cast<float>(valid * (cu + inv_u * (m(0, 0) * out_x + m(0, 1) * out_y)) - (1.0 - valid));
      my[u] = static_cast<float>(valid * (cv_ + inv_v * (m(1, 0) * out_x + m(1, 1) * out_y)) - (1.0 - valid));
    }
  }
}

}  // namespace

double FoldRadiusMm(const model::Distortion& distortion, double max_radius_mm) {
  return model::FoldRadiusMm(distortion, max_radius_mm, kMinRadialDerivative);
}

UndistortMap BuildUndistortMap(const model::Distortion& distortion, const model::TopographerCamera& camera) {
  UndistortMap out;
  BuildUndistortMap(distortion, camera, &out);
  return out;
}

double SensorFoldRadiusMm(const model::Distortion& distortion, const model::TopographerCamera& camera) {
  const Eigen::Vector2d centre = model::DistortionCentreMm(distortion);
  double max_r = 0;
  for (const double u : {-0.5, camera.width_px - 0.5}) {
    for (const double v : {-0.5, camera.height_px - 0.5}) {
      max_r = std::max(max_r, (camera.DetectionPlaneFromPixel({u, v}) - centre).norm());
    }
  }
  return FoldRadiusMm(distortion, max_r * 1.001);
}

namespace {

// Calls fill(kernel) with the per-pixel forward model (mm -> mm) of `distortion`: the model is chosen once, outside
// the pixel loop, and the kernel is a few multiply-adds.
template <typename Fill>
void WithKernel(const model::Distortion& distortion, const Fill& fill) {
  if (const auto* s = std::get_if<model::SeidelParams>(&distortion)) {
    const auto params = s->AsArray();
    const double c = model::SeidelRadial::Coefficient(params.data());  // once, not per pixel
    const double cx = s->centre_x_mm, cy = s->centre_y_mm;
    fill([c, cx, cy](double x, double y, double* ox, double* oy) {
      const double in[2] = {x, y};
      double out[2];
      model::SeidelRadial::DistortWithCoefficient(c, cx, cy, in, out);
      *ox = out[0];
      *oy = out[1];
    });
  } else {
    const auto b = std::get<model::LensParams>(distortion);
    const double inv_f = 1.0 / b.focal_mm;  // a multiply per pixel instead of a divide
    std::visit(
        [&](auto lens) {
          using Lens = decltype(lens);  // the model chosen here too, not per pixel
          fill([b, inv_f](double x, double y, double* ox, double* oy) {
            const double xn[2] = {(x - b.centre_x_mm) * inv_f, (y - b.centre_y_mm) * inv_f};
            double xd[2];
            Lens::DistortNormalized(b.k.data(), xn, xd);
            *ox = b.centre_x_mm + b.focal_mm * xd[0];
            *oy = b.centre_y_mm + b.focal_mm * xd[1];
          });
        },
        b.model);
  }
}

}  // namespace

void BuildUndistortMap(const model::Distortion& distortion, const model::TopographerCamera& camera,
                       UndistortMap* map) {
  UndistortMap& out = *map;
  out.invalid_px = 0;
  out.map_x.create(camera.height_px, camera.width_px, CV_32FC1);
  out.map_y.create(camera.height_px, camera.width_px, CV_32FC1);
  const Eigen::Vector2d centre = model::DistortionCentreMm(distortion);
  out.fold_radius_mm = SensorFoldRadiusMm(distortion, camera);
  const double fold = out.fold_radius_mm;
  cv::Mat* mx = &out.map_x;
  cv::Mat* my = &out.map_y;
  WithKernel(distortion, [&](const auto& kernel) {
    cv::parallel_for_(cv::Range(0, camera.height_px), [&](const cv::Range& r) {
      FillRows(kernel, camera, centre, fold, r.start, r.end, mx, my);
    });
  });
  if (std::isfinite(fold)) out.invalid_px = cv::countNonZero(out.map_x == -1.f);
}

cv::Mat UndistortImage(const cv::Mat& distorted, const model::Distortion& distortion,
                       const model::TopographerCamera& camera, int* invalid_px, int interpolation,
                       double border_value) {
  if (distorted.cols != camera.width_px || distorted.rows != camera.height_px) {
    throw util::InputError("UndistortImage: image size differs from the camera's sensor size");
  }
  // Bands of rows, as cv::undistort works: each band's map (2 x 4 B x width x kBandRows, ~1 MB at 4000 px) is built
  // and used while it is in cache, instead of two 48 MB maps written to memory and read back.
  constexpr int kBandRows = 32;
  const Eigen::Vector2d centre = model::DistortionCentreMm(distortion);
  const double fold = SensorFoldRadiusMm(distortion, camera);
  cv::Mat out(distorted.size(), distorted.type());
  const int bands = (camera.height_px + kBandRows - 1) / kBandRows;
  std::atomic<int> invalid{0};
  WithKernel(distortion, [&](const auto& kernel) {
    cv::parallel_for_(cv::Range(0, bands), [&](const cv::Range& r) {
      cv::Mat mx(kBandRows, camera.width_px, CV_32FC1), my(kBandRows, camera.width_px, CV_32FC1);
      for (int band = r.start; band < r.end; ++band) {
        const int r0 = band * kBandRows, r1 = std::min(camera.height_px, r0 + kBandRows);
        FillRows(kernel, camera, centre, fold, r0, r1, &mx, &my, r0);
        if (std::isfinite(fold)) invalid += cv::countNonZero(mx.rowRange(0, r1 - r0) == -1.f);
        cv::Mat dst = out.rowRange(r0, r1);
        cv::remap(distorted, dst, mx.rowRange(0, r1 - r0), my.rowRange(0, r1 - r0), interpolation,
                  cv::BORDER_CONSTANT, cv::Scalar::all(border_value));
      }
    });
  });
  if (invalid_px) *invalid_px = invalid;
  return out;
}

cv::Mat UndistortImage(const cv::Mat& distorted, const UndistortMap& map, int interpolation, double border_value) {
  if (distorted.size() != map.map_x.size()) {
    throw util::InputError("UndistortImage: image size differs from the camera's sensor size");
  }
  cv::Mat out;
  cv::remap(distorted, out, map.map_x, map.map_y, interpolation, cv::BORDER_CONSTANT, cv::Scalar::all(border_value));
  return out;
}

}  // namespace topocal::correct

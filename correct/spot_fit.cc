#include "correct/spot_detail.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <ceres/ceres.h>
#include <ceres/tiny_solver.h>

namespace topocal::correct::detail {
namespace {

// Elliptical Gaussian with constant background; the inverse covariance parametrised by its Cholesky factor
// (l0, l1, l2 with L = [[l0, 0], [l1, l2]]) so it stays positive definite without bounds.
struct GaussianResidual {
  double u, v, value;
  template <typename T>
  bool operator()(const T* p, T* residual) const {
    // p: amplitude, cx, cy, l0, l1, l2, background
    const T dx = T(u) - p[1], dy = T(v) - p[2];
    const T a = p[3] * dx + p[4] * dy;  // L^T d
    const T b = p[5] * dy;
    residual[0] = p[0] * exp(T(-0.5) * (a * a + b * b)) + p[6] - T(value);
    return true;
  }
};

// A window's pixels for the PSF fit: position relative to the window origin, value (DN, background included) and
// the noise standard deviation assigned to it.
struct FitPixel {
  int u, v;  // relative to (u0, v0)
  double value_dn;
  double sd_dn;
};

// Pixel-integrated isotropic Gaussian PSF + constant background, residuals weighted by 1 / sd. Parameters:
// flux / flux0, centre u and v relative to the window origin (px), sigma (px), background (DN). The pixel integral
// is separable, E_u(c) = Phi((c + 1/2 - u) / s) - Phi((c - 1/2 - u) / s), so the erf terms are computed once per
// column and per row. Analytic Jacobian: TinySolver (Ceres' small dense LM without a Problem's per-call set-up
// cost) needs one, and the model is simple enough to write it exactly.
struct PsfCost {
  using Scalar = double;
  enum { NUM_RESIDUALS = Eigen::Dynamic, NUM_PARAMETERS = 5 };
  const std::vector<FitPixel>* pixels;
  int cols, rows;
  double flux0;
  double bg0, bg_scale;  // background = bg0 + p[4] bg_scale: all parameters O(1), so that the solver's relative
                         // step tolerance means the same on 8- and 16-bit images
  int NumResiduals() const { return static_cast<int>(pixels->size()); }
  bool operator()(const double* p, double* residuals, double* jacobian) const {
    const double sigma = p[3];
    if (!(sigma > 0.05)) return false;
    thread_local std::vector<double> eu, du, su, ev, dv, sv;
    const auto profile = [sigma](int n, double centre, std::vector<double>& e, std::vector<double>& d,
                                 std::vector<double>& s) {
      e.resize(n);
      d.resize(n);
      s.resize(n);
      constexpr double kInvSqrt2Pi = 0.3989422804014327;
      for (int c = 0; c < n; ++c) {
        const double a = (c + 0.5 - centre) / sigma, b = (c - 0.5 - centre) / sigma;
        const double pa = kInvSqrt2Pi * std::exp(-0.5 * a * a), pb = kInvSqrt2Pi * std::exp(-0.5 * b * b);
        e[c] = 0.5 * (std::erfc(-a * M_SQRT1_2) - std::erfc(-b * M_SQRT1_2));
        d[c] = -(pa - pb) / sigma;          // dE / dcentre
        s[c] = -(pa * a - pb * b) / sigma;  // dE / dsigma
      }
    };
    profile(cols, p[1], eu, du, su);
    profile(rows, p[2], ev, dv, sv);
    const double flux = p[0] * flux0;
    const int n = NumResiduals();
    for (int i = 0; i < n; ++i) {
      const FitPixel& px = (*pixels)[i];
      const double w = 1.0 / px.sd_dn;
      const double e = eu[px.u] * ev[px.v];
      residuals[i] = w * (flux * e + bg0 + p[4] * bg_scale - px.value_dn);
      if (jacobian) {
        jacobian[i] = w * flux0 * e;
        jacobian[n + i] = w * flux * du[px.u] * ev[px.v];
        jacobian[2 * n + i] = w * flux * eu[px.u] * dv[px.v];
        jacobian[3 * n + i] = w * flux * (su[px.u] * ev[px.v] + eu[px.u] * sv[px.v]);
        jacobian[4 * n + i] = w * bg_scale;
      }
    }
    return true;
  }
  // The model's signal above background at pixel i (DN).
  double Signal(const double* p, const FitPixel& px) const {
    const auto e = [&](int c, double centre) {
      const double a = (c + 0.5 - centre) / p[3], b = (c - 0.5 - centre) / p[3];
      return 0.5 * (std::erfc(-a * M_SQRT1_2) - std::erfc(-b * M_SQRT1_2));
    };
    return p[0] * flux0 * e(px.u, p[1]) * e(px.v, p[2]);
  }
};

// Is the spot's profile that of the PSF (a Gaussian) or flat-topped (the image of a screen disc several PSF widths
// across)? A Gaussian of peak p covers 2 pi s^2 ln(p / L) pixels above level L, so the share of the thresholded
// pixels above half the peak is ln 2 / ln(p / t) (t: threshold above background); a flat top has nearly all of
// them above half its plateau. The spot is taken as PSF-like when the share is nearer the Gaussian's value than 1.
// On flat-topped spots the PSF model does not hold and its fit is worse than the centroid (docs/spot-noise.md).
bool PsfLike(const std::vector<double>& values, double peak_dn, double threshold_above_bg_dn) {
  if (values.empty() || !(peak_dn > 1.01 * threshold_above_bg_dn) || !(threshold_above_bg_dn > 0)) return true;
  const double gaussian_share = std::log(2.0) / std::log(peak_dn / threshold_above_bg_dn);
  const auto above_half = std::count_if(values.begin(), values.end(), [&](double w) { return w > 0.5 * peak_dn; });
  const double share = static_cast<double>(above_half) / values.size();
  return share <= 0.5 * (gaussian_share + 1.0);
}

// The weighted PSF fit of one component. `read_var` and `inv_gain` make the noise model; `first`: weights from the
// read noise only (the model signal is not known yet). Returns false (centre untouched) if the fit fails.
bool FitPsf(const cv::Mat& image_box, const cv::Mat& labels, const Component& comp, double bg, double read_var,
            double inv_gain, double* params, std::vector<FitPixel>* pixels) {
  pixels->clear();
  const int c0 = comp.roi.x, r0 = comp.roi.y;
  for (int r = r0; r < r0 + comp.roi.height; ++r) {
    const int* lab = labels.ptr<int>(r);
    const uint8_t* win = comp.window.ptr<uint8_t>(r - r0) - c0;
    for (int c = c0; c < c0 + comp.roi.width; ++c) {
      if (!win[c] || (lab[c] != 0 && lab[c] != comp.label)) continue;
      const double value = At(image_box, r, c);
      if (Saturates(image_box, value)) continue;  // clipped: carries no information on the spot's shape
      pixels->push_back({c - c0, r - r0, value, std::sqrt(read_var)});
    }
  }
  if (pixels->size() < 8) return false;
  PsfCost cost{pixels, comp.roi.width, comp.roi.height, comp.spot.flux_dn, bg, std::sqrt(read_var)};
  if (inv_gain > 0) {
    for (auto& px : *pixels) px.sd_dn = std::sqrt(read_var + std::max(0.0, cost.Signal(params, px)) * inv_gain);
  }
  ceres::TinySolver<PsfCost> solver;
  // Parameters are O(1) (flux ratio, centre and width in px, background in noise sigmas): a relative step of 1e-7
  // is < 1e-6 px, far below the centre's noise (>= 1e-3 px).
  solver.options.max_num_iterations = 30;
  solver.options.parameter_tolerance = 1e-7;
  solver.options.function_tolerance = 1e-10;
  solver.options.gradient_tolerance = 1e-10;
  Eigen::Matrix<double, 5, 1> x = Eigen::Map<Eigen::Matrix<double, 5, 1>>(params);
  const auto summary = solver.Solve(cost, &x);
  if (summary.status == decltype(solver)::HIT_MAX_ITERATIONS || !x.allFinite() || !(x[3] > 0.05)) return false;
  std::copy(x.data(), x.data() + 5, params);
  return true;
}

}  // namespace

void RefineByGaussianFit(const cv::Mat& image_box, const cv::Mat& labels, double bg, std::vector<Component>* comps) {
  for (auto& comp : *comps) {
    DetectedSpot& s = comp.spot;
    const int c0 = comp.roi.x, r0 = comp.roi.y, c1 = c0 + comp.roi.width - 1, r1 = r0 + comp.roi.height - 1;
    const cv::Mat& window = comp.window;
    const int k = comp.label;
    const int area = s.area_px;
    const double peak = s.peak_dn;
    // Initial shape from the thresholded area: a Gaussian whose half-maximum disc has that area.
    const double sigma0 = std::max(0.7, std::sqrt(area / M_PI) / 1.1774);
    double p[7] = {peak, s.centre_px.x(), s.centre_px.y(), 1.0 / sigma0, 0.0, 1.0 / sigma0, 0.0};
    ceres::Problem problem;
    for (int r = r0; r <= r1; ++r) {
      const int* lab = labels.ptr<int>(r);
      const uint8_t* win = window.ptr<uint8_t>(r - r0) - c0;
      for (int c = c0; c <= c1; ++c) {
        if (!win[c] || (lab[c] != 0 && lab[c] != k)) continue;
        problem.AddResidualBlock(new ceres::AutoDiffCostFunction<GaussianResidual, 1, 7>(
                                     new GaussianResidual{double(c), double(r), At(image_box, r, c) - bg}),
                                 nullptr, p);
      }
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = 50;
    so.function_tolerance = 1e-12;
    so.parameter_tolerance = 1e-12;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    const Eigen::Vector2d fit(p[1], p[2]);
    s.fit_converged = summary.termination_type == ceres::CONVERGENCE && std::isfinite(p[1]) && std::isfinite(p[2]) &&
                      (fit - s.centre_px).norm() < 2.0;  // a fit that wanders off the blob is not a centre
    if (s.fit_converged) s.centre_px = fit;
  }
}

double RefineByPsfFit(const cv::Mat& image_box, const cv::Mat& labels, double bg, double threshold_dn, double read_var,
                      double gain_e_per_dn, std::vector<Component>* comps) {
  std::vector<Component>& c = *comps;
  std::vector<std::array<double, 5>> params(c.size(), {0, 0, 0, 0, 0});
  std::vector<char> ok(c.size(), 0);
  std::vector<FitPixel> pixels;
  // Pass 1: read-noise weights. Its residuals against the model signal give the gain: E[r^2] = read + s / gain,
  // so 1 / gain = sum((r^2 - read) s) / sum(s^2) over the spots' pixels (least squares through the origin).
  double num = 0, den = 0;
  for (size_t i = 0; i < c.size(); ++i) {
    const auto& comp = c[i];
    const DetectedSpot& s = comp.spot;
    if (!PsfLike(comp.values, s.peak_dn, threshold_dn - bg)) continue;  // flat-topped: keeps its centroid
    const double sigma0 = std::max(0.7, std::sqrt(s.area_px / M_PI) / 1.1774);
    params[i] = {1.0, s.centre_px.x() - comp.roi.x, s.centre_px.y() - comp.roi.y, sigma0, 0.0};
    ok[i] = FitPsf(image_box, labels, comp, bg, read_var, 0.0, params[i].data(), &pixels);
    if (!ok[i] || gain_e_per_dn > 0 || (comp.spot.flags & (kNearBlob | kTruncated))) continue;
    PsfCost cost{&pixels, comp.roi.width, comp.roi.height, comp.spot.flux_dn, bg, std::sqrt(read_var)};
    for (const auto& px : pixels) {
      const double sig = cost.Signal(params[i].data(), px);
      const double res = px.value_dn - (bg + params[i][4] * cost.bg_scale) - sig;
      num += (res * res - read_var) * sig;
      den += sig * sig;
    }
  }
  double inv_gain = gain_e_per_dn > 0 ? 1.0 / gain_e_per_dn : (den > 0 ? std::max(0.0, num / den) : 0.0);
  // Pass 2: the noise model's weights from pass 1's model signal (a pure read-noise model needs no second pass).
  for (size_t i = 0; i < c.size(); ++i) {
    DetectedSpot& s = c[i].spot;
    if (ok[i] && inv_gain > 0) {
      ok[i] = FitPsf(image_box, labels, c[i], bg, read_var, inv_gain, params[i].data(), &pixels);
    }
    if (!ok[i] && params[i][3] == 0) continue;  // not fitted (flat-topped): the centroid stands
    const Eigen::Vector2d fit(params[i][1] + c[i].roi.x, params[i][2] + c[i].roi.y);
    s.fit_converged = ok[i] && (fit - s.centre_px).norm() < 2.0;  // a fit that wanders off the blob is no centre
    if (s.fit_converged) s.centre_px = fit;
  }
  return inv_gain > 0 ? 1.0 / inv_gain : 0.0;
}

}  // namespace topocal::correct::detail

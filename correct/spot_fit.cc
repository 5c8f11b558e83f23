#include "correct/spot_detail.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <ceres/ceres.h>
#include <ceres/tiny_solver.h>
#include <opencv2/imgproc.hpp>

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
    if (!(sigma > 0.05)) {
      // A step to a non-physical width. Ceres' TinySolver (2.1) ignores a false return at a trial point and goes
      // on with residuals never written (uninitialised memory: the same image gave different centres run to run),
      // so the step is made unattractive instead: a huge, finite cost that the solver rejects.
      for (int i = 0; i < NumResiduals(); ++i) residuals[i] = 1e10;
      if (jacobian) std::fill(jacobian, jacobian + 5 * NumResiduals(), 0.0);
      return true;
    }
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

// A spot whose level comes within 3 noise sigmas of full scale has its upper tail clipped, and leaving the clipped
// pixels out would shrink its variance: it gives no evidence on the gain. The level decides, not the pixels' noise
// (which would select the spots whose noise happened to stay low); the sigma assumes >= 1 e-/DN (an upper bound).
bool ClearOfFullScale(const cv::Mat& image, double level_dn, double read_var, double bg) {
  const double full = image.depth() == CV_8U ? 255.0 : image.depth() == CV_16U ? 65535.0 : HUGE_VAL;
  return level_dn + 3.0 * std::sqrt(read_var + std::max(0.0, level_dn - bg)) < full;
}

// Is a fit's residual noise, or the model's misfit (an elliptical spot that passed for PSF-like, a neighbour's
// tail)? A misfit is smooth across the window, so adjacent residuals are alike; noise's are independent (the fit's
// leverage makes them slightly anti-correlated). The residuals of horizontally and vertically adjacent pixels are
// taken as structured when their correlation exceeds 3 standard errors of a zero one (1 / sqrt(pairs)).
bool ResidualIsStructured(const std::vector<FitPixel>& pixels, const std::vector<double>& residuals, int cols,
                          int rows) {
  std::vector<int> at(static_cast<size_t>(cols) * rows, -1);
  for (size_t i = 0; i < pixels.size(); ++i) at[static_cast<size_t>(pixels[i].v) * cols + pixels[i].u] = static_cast<int>(i);
  double cross = 0, square = 0;
  int pairs = 0;
  for (size_t i = 0; i < pixels.size(); ++i) {
    const FitPixel& p = pixels[i];
    for (const auto& [du, dv] : {std::pair{1, 0}, std::pair{0, 1}}) {
      if (p.u + du >= cols || p.v + dv >= rows) continue;
      const int j = at[static_cast<size_t>(p.v + dv) * cols + p.u + du];
      if (j < 0) continue;
      cross += residuals[i] * residuals[j];
      square += 0.5 * (residuals[i] * residuals[i] + residuals[j] * residuals[j]);
      ++pairs;
    }
  }
  return pairs == 0 || !(square > 0) || cross / square > 3.0 / std::sqrt(static_cast<double>(pairs));
}

// The spots' evidence on 1 / gain: least squares through the origin, num / den, from `spots` spots.
struct GainEvidence {
  double num = 0, den = 0;
  int spots = 0;
};

// Pass 1's evidence on the gain from one spot's read-noise-weighted fit: the fit absorbs part of each pixel's noise
// (its leverage), most at the bright pixels that carry the shot noise, so the squared residuals are compared with
// their expectation under the noise model rather than with the pixel variance itself. With M = I - H the residual
// maker of the (uniformly weighted) linearised fit and var_j = read_var + s_j / gain,
//   E[r_i^2] = sum_j M_ij^2 var_j = read_var (1 - h_ii) + a_i / gain,   a_i = s_i (1 - 2 h_ii) + q_i' S q_i,
// q_i = (J'J)^-1 j_i, S = J' diag(s) J — O(n) per spot, not O(n^2). Adds sum (r_i^2 - read_var (1 - h_ii)) a_i and
// sum a_i^2 to the evidence; false (nothing added) when the spot gives none.
bool AccumulateGainEvidence(const cv::Mat& image_box, const Component& comp, const std::vector<FitPixel>& pixels,
                            const double* params, double bg, double read_var, GainEvidence* evidence) {
  PsfCost cost{&pixels, comp.roi.width, comp.roi.height, comp.spot.flux_dn, bg, std::sqrt(read_var)};
  const int n = cost.NumResiduals();
  std::vector<double> residuals(n), jac(static_cast<size_t>(n) * 5);
  if (!cost(params, residuals.data(), jac.data())) return false;
  if (ResidualIsStructured(pixels, residuals, comp.roi.width, comp.roi.height)) return false;
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 5>> J(jac.data(), n, 5);
  Eigen::VectorXd s(n);
  for (int i = 0; i < n; ++i) s[i] = std::max(0.0, cost.Signal(params, pixels[i]));
  const double background = bg + params[4] * cost.bg_scale;
  if (n == 0 || !ClearOfFullScale(image_box, background + s.maxCoeff(), read_var, bg)) return false;
  const Eigen::Matrix<double, 5, 5> JtJ = J.transpose() * J;
  const Eigen::LDLT<Eigen::Matrix<double, 5, 5>> ldlt(JtJ);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0)) return false;
  const Eigen::Matrix<double, 5, 5> S = J.transpose() * s.asDiagonal() * J;
  for (int i = 0; i < n; ++i) {
    const Eigen::Matrix<double, 5, 1> j = J.row(i).transpose();
    const Eigen::Matrix<double, 5, 1> q = ldlt.solve(j);
    const double h = j.dot(q);
    const double a = s[i] * (1.0 - 2.0 * h) + q.dot(S * q);
    const double r = residuals[i] * pixels[i].sd_dn;  // in DN
    evidence->num += (r * r - read_var * (1.0 - h)) * a;
    evidence->den += a * a;
  }
  return true;
}

// The same evidence from a flat-topped spot (the image of a screen disc several PSF widths across), which no model
// here fits: on its plateau the signal is constant, so two horizontally adjacent plateau pixels differ by noise
// alone, E[(I2 - I1)^2] / 2 = read_var + s / gain. The plateau must be flat to well below the noise — two pixels in
// from the half-level edge the PSF's slope is still ~5 % of the level per pixel, 15x a 16-bit spot's noise — so it
// is the pixels at least 4 PSF sigmas + 1 px inside the half-level contour, the PSF's sigma measured from the
// spot's own edge: the radii of the areas above 10 % and 90 % of the level differ by 2.563 sigma. The level is the
// median of the pixels above half the peak. Adds sum (d^2 / 2 - read_var) s and
// sum s^2 over disjoint pairs; false when there are none.
bool AccumulatePlateauGainEvidence(const cv::Mat& image_box, const cv::Mat& labels, const Component& comp, double bg,
                                   double read_var, GainEvidence* evidence) {
  std::vector<double> upper;
  for (double v : comp.values) {
    if (v > 0.5 * comp.spot.peak_dn) upper.push_back(v);
  }
  if (upper.size() < 8) return false;
  std::nth_element(upper.begin(), upper.begin() + upper.size() / 2, upper.end());
  const double level = upper[upper.size() / 2];
  if (!ClearOfFullScale(image_box, bg + level, read_var, bg)) return false;
  const auto area_above = [&](double share) {
    return std::count_if(comp.values.begin(), comp.values.end(), [&](double v) { return v > share * level; });
  };
  const double psf_sigma =
      (std::sqrt(area_above(0.1) / M_PI) - std::sqrt(area_above(0.9) / M_PI)) / 2.563;
  const float inside = static_cast<float>(4.0 * std::max(psf_sigma, 0.5) + 1.0);
  if (std::sqrt(area_above(0.5) / M_PI) <= inside) return false;  // no pixel that deep: spare the transform
  const cv::Rect& roi = comp.roi;
  cv::Mat half(roi.size(), CV_8U, cv::Scalar(0));
  for (int r = 0; r < roi.height; ++r) {
    for (int c = 0; c < roi.width; ++c) {
      half.at<uint8_t>(r, c) = labels.at<int>(r + roi.y, c + roi.x) == comp.label &&
                               At(image_box, r + roi.y, c + roi.x) - bg > 0.5 * level;
    }
  }
  cv::Mat depth;
  cv::distanceTransform(half, depth, cv::DIST_L2, cv::DIST_MASK_5);  // chamfer: within 2 % of Euclidean
  bool any = false;
  for (int r = 0; r < roi.height; ++r) {
    const float* d = depth.ptr<float>(r);
    for (int c = 0; c + 1 < roi.width; c += 2) {  // disjoint pairs: independent differences
      if (d[c] < inside || d[c + 1] < inside) continue;
      const double a = At(image_box, r + roi.y, c + roi.x), b = At(image_box, r + roi.y, c + 1 + roi.x);
      const double signal = 0.5 * (a + b) - bg;
      evidence->num += (0.5 * (b - a) * (b - a) - read_var) * signal;
      evidence->den += signal * signal;
      any = true;
    }
  }
  return any;
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

NoiseModelFit RefineByPsfFit(const cv::Mat& image_box, const cv::Mat& labels, double bg, double threshold_dn, double read_var,
                      double gain_e_per_dn, std::vector<Component>* comps) {
  std::vector<Component>& c = *comps;
  std::vector<std::array<double, 5>> params(c.size(), {0, 0, 0, 0, 0});
  std::vector<char> ok(c.size(), 0);
  std::vector<FitPixel> pixels;
  // Pass 1: read-noise weights. The residuals of its fits against their expectation under the noise model, and the
  // plateau differences of flat-topped spots, give the gain (least squares through the origin for 1 / gain) from
  // the spots that no other blob's light reaches.
  GainEvidence evidence;
  for (size_t i = 0; i < c.size(); ++i) {
    const auto& comp = c[i];
    const DetectedSpot& s = comp.spot;
    const bool clean = gain_e_per_dn <= 0 && !(s.flags & (kNearBlob | kTruncated)) && comp.neighbours.empty();
    if (!PsfLike(comp.values, s.peak_dn, threshold_dn - bg)) {  // flat-topped: keeps its centroid
      if (clean) evidence.spots += AccumulatePlateauGainEvidence(image_box, labels, comp, bg, read_var, &evidence);
      continue;
    }
    const double sigma0 = std::max(0.7, std::sqrt(s.area_px / M_PI) / 1.1774);
    params[i] = {1.0, s.centre_px.x() - comp.roi.x, s.centre_px.y() - comp.roi.y, sigma0, 0.0};
    ok[i] = FitPsf(image_box, labels, comp, bg, read_var, 0.0, params[i].data(), &pixels);
    if (ok[i] && clean) evidence.spots += AccumulateGainEvidence(image_box, comp, pixels, params[i].data(), bg, read_var, &evidence);
  }
  NoiseModelFit noise;
  noise.evidence_spots = evidence.spots;
  noise.gain_measured = gain_e_per_dn <= 0 && evidence.spots >= kMinGainEvidenceSpots && evidence.den > 0;
  const double inv_gain = gain_e_per_dn > 0 ? 1.0 / gain_e_per_dn
                          : noise.gain_measured ? std::max(0.0, evidence.num / evidence.den)
                                              : 0.0;
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
  noise.gain_e_per_dn = inv_gain > 0 ? 1.0 / inv_gain : 0.0;
  return noise;
}

}  // namespace topocal::correct::detail

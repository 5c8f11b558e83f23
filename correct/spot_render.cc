#include "correct/spot_render.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/LU>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include "util/io.h"

namespace topocal::correct {
namespace {

double Phi(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

// Adds one spot's noiseless signal to the float image `acc` (signal above background, DN).
void AddPsfSpot(const SpotToRender& s, double sigma, double peak, cv::Mat* acc) {
  const int half = static_cast<int>(std::ceil(5.0 * sigma)) + 1;
  const int u0 = std::max(0, static_cast<int>(std::floor(s.centre_px.x())) - half);
  const int u1 = std::min(acc->cols - 1, static_cast<int>(std::ceil(s.centre_px.x())) + half);
  const int v0 = std::max(0, static_cast<int>(std::floor(s.centre_px.y())) - half);
  const int v1 = std::min(acc->rows - 1, static_cast<int>(std::ceil(s.centre_px.y())) + half);
  if (u0 > u1 || v0 > v1) return;
  // Pixel-area integral of a Gaussian with peak value `peak`: peak * 2 pi sigma^2 * (dPhi_x)(dPhi_y).
  const double norm = peak * 2.0 * M_PI * sigma * sigma;
  std::vector<double> wx(u1 - u0 + 1), wy(v1 - v0 + 1);
  for (int u = u0; u <= u1; ++u) {
    wx[u - u0] = Phi((u + 0.5 - s.centre_px.x()) / sigma) - Phi((u - 0.5 - s.centre_px.x()) / sigma);
  }
  for (int v = v0; v <= v1; ++v) {
    wy[v - v0] = Phi((v + 0.5 - s.centre_px.y()) / sigma) - Phi((v - 0.5 - s.centre_px.y()) / sigma);
  }
  for (int v = v0; v <= v1; ++v) {
    float* row = acc->ptr<float>(v);
    for (int u = u0; u <= u1; ++u) row[u] += static_cast<float>(norm * wx[u - u0] * wy[v - v0]);
  }
}

void AddEllipseSpot(const SpotToRender& s, double sigma, double peak, cv::Mat* acc) {
  const Eigen::Matrix2d inv = s.shape_px.inverse();
  const double extent = s.shape_px.norm() + 5.0 * sigma + 1.0;  // Frobenius norm bounds the largest semi-axis
  const int u0 = std::max(0, static_cast<int>(std::floor(s.centre_px.x() - extent)));
  const int u1 = std::min(acc->cols - 1, static_cast<int>(std::ceil(s.centre_px.x() + extent)));
  const int v0 = std::max(0, static_cast<int>(std::floor(s.centre_px.y() - extent)));
  const int v1 = std::min(acc->rows - 1, static_cast<int>(std::ceil(s.centre_px.y() + extent)));
  // Symmetric 3x3 sub-pixel grid: its centroid is the pixel centre, so sampling adds no systematic shift.
  constexpr double kSub[3] = {-1.0 / 3.0, 0.0, 1.0 / 3.0};
  for (int v = v0; v <= v1; ++v) {
    float* row = acc->ptr<float>(v);
    for (int u = u0; u <= u1; ++u) {
      double sum = 0;
      for (const double dv : kSub) {
        for (const double du : kSub) {
          const Eigen::Vector2d d(u + du - s.centre_px.x(), v + dv - s.centre_px.y());
          const double dist = d.norm();
          const double t = (inv * d).norm();  // 1 on the ellipse's edge
          // Radius of the ellipse in this direction: dist / t; signed distance inside the edge: dist / t - dist.
          const double inside = t > 1e-12 ? dist / t - dist : extent;
          sum += sigma > 0 ? Phi(inside / sigma) : (inside >= 0 ? 1.0 : 0.0);
        }
      }
      row[u] += static_cast<float>(peak * sum / 9.0);
    }
  }
}

// A smooth random field of unit standard deviation: Gaussian noise on a grid `cell` pixels apart, interpolated.
cv::Mat Texture(int width, int height, int cell, std::mt19937* rng) {
  std::normal_distribution<float> normal(0.f, 1.f);
  cv::Mat coarse(height / cell + 2, width / cell + 2, CV_32FC1);
  for (int r = 0; r < coarse.rows; ++r) {
    for (int c = 0; c < coarse.cols; ++c) coarse.at<float>(r, c) = normal(*rng);
  }
  cv::Mat fine;
  cv::resize(coarse, fine, cv::Size(coarse.cols * cell, coarse.rows * cell), 0, 0, cv::INTER_CUBIC);
  cv::Scalar mean, sd;
  cv::meanStdDev(fine, mean, sd);
  return (fine(cv::Rect(0, 0, width, height)) - mean[0]) / std::max(sd[0], 1e-6);
}

// The lids' skin: level plus texture (two scales: ~24 px patches and ~5 px grain) where the lids hide the pattern.
void AddSkin(const SpotRenderOptions& o, cv::Mat* acc) {
  std::mt19937 rng(o.seed ^ 0x5eed5u);
  const cv::Mat patches = Texture(acc->cols, acc->rows, 24, &rng);
  const cv::Mat grain = Texture(acc->cols, acc->rows, 5, &rng);
  for (int v = 0; v < acc->rows; ++v) {
    float* a = acc->ptr<float>(v);
    const float* p = patches.ptr<float>(v);
    const float* g = grain.ptr<float>(v);
    for (int u = 0; u < acc->cols; ++u) {
      if (!o.lids.Hides(u, v)) continue;
      a[u] += static_cast<float>(std::max(0.0, o.skin_dn + o.skin_texture_dn * (0.8 * p[u] + 0.6 * g[u])));
    }
  }
}

// The pattern's centre and radius from the extent LidsOver measured.
Eigen::Vector2d PatternCentre(const Lids& e) { return {e.u_mid_px, 0.5 * (e.v_top_px + e.v_bottom_px)}; }
double PatternRadius(const Lids& e) { return 0.5 * (e.v_bottom_px - e.v_top_px); }

// The iris behind the pattern (Artefacts): radial streaks (a random function of the angle) times a smooth radial
// profile, plus grain; the pupil and the sclera beyond 1.3 radii left at the background.
void AddIris(const SpotRenderOptions& o, cv::Mat* acc) {
  std::mt19937 rng(o.seed ^ 0x1815u);
  std::normal_distribution<double> normal(0.0, 1.0);
  constexpr int kStreaks = 240;
  std::vector<double> streak(kStreaks);
  for (auto& v : streak) v = normal(rng);
  const cv::Mat grain = Texture(acc->cols, acc->rows, 4, &rng);
  const Eigen::Vector2d c = PatternCentre(o.lids);
  const double radius = PatternRadius(o.lids);
  if (!(radius > 0)) return;
  for (int v = 0; v < acc->rows; ++v) {
    float* a = acc->ptr<float>(v);
    const float* g = grain.ptr<float>(v);
    for (int u = 0; u < acc->cols; ++u) {
      const double rho = std::hypot(u - c.x(), v - c.y()) / radius;
      if (rho < 0.3 || rho > 1.35) continue;
      // Smooth edges over 0.05 radii at the pupil and at the limbus.
      const double edge = std::clamp((rho - 0.3) / 0.05, 0.0, 1.0) * std::clamp((1.35 - rho) / 0.05, 0.0, 1.0);
      const double t = (std::atan2(v - c.y(), u - c.x()) + M_PI) / (2 * M_PI) * kStreaks;
      const int i = static_cast<int>(t) % kStreaks;
      const double f = t - std::floor(t);
      const double s = (1 - f) * streak[i] + f * streak[(i + 1) % kStreaks];
      const double level = o.artefacts.iris_dn * (1.0 + 0.3 * s + 0.25 * g[u]);
      a[u] += static_cast<float>(edge * std::max(0.0, level));
    }
  }
}

// The eye's movement during the exposure: `acc` convolved with a centred straight segment (64 sub-samples splatted
// bilinearly into the kernel, normalised), so that a spot's centre does not move.
void MotionBlur(const Artefacts& a, cv::Mat* acc) {
  const double len = a.motion_blur_px;
  const int half = static_cast<int>(std::ceil(0.5 * len)) + 1;
  cv::Mat kernel(2 * half + 1, 2 * half + 1, CV_32FC1, cv::Scalar(0));
  const Eigen::Vector2d dir(std::cos(a.motion_blur_deg * M_PI / 180), std::sin(a.motion_blur_deg * M_PI / 180));
  constexpr int kSamples = 64;
  for (int k = 0; k < kSamples; ++k) {
    const Eigen::Vector2d p = Eigen::Vector2d::Constant(half) + ((k + 0.5) / kSamples - 0.5) * len * dir;
    const int u = static_cast<int>(std::floor(p.x())), v = static_cast<int>(std::floor(p.y()));
    const double fu = p.x() - u, fv = p.y() - v;
    kernel.at<float>(v, u) += static_cast<float>((1 - fu) * (1 - fv));
    kernel.at<float>(v, u + 1) += static_cast<float>(fu * (1 - fv));
    kernel.at<float>(v + 1, u) += static_cast<float>((1 - fu) * fv);
    kernel.at<float>(v + 1, u + 1) += static_cast<float>(fu * fv);
  }
  kernel /= cv::sum(kernel)[0];
  cv::filter2D(*acc, *acc, -1, kernel, cv::Point(-1, -1), 0, cv::BORDER_CONSTANT);
}

// Lash shadows (Artefacts): curved bands from the upper lid's margin, drawn anti-aliased into a mask, softened, and
// multiplied into the light.
void ShadowLashes(const SpotRenderOptions& o, cv::Mat* acc) {
  std::mt19937 rng(o.seed ^ 0x1a54u);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const Lids& lids = o.lids;
  const Eigen::Vector2d c = PatternCentre(lids);
  const double radius = PatternRadius(lids);
  if (!(radius > 0)) return;
  cv::Mat mask(acc->rows, acc->cols, CV_8UC1, cv::Scalar(0));
  double widest = 1;
  for (int k = 0; k < o.artefacts.lashes; ++k) {
    const double u_root = c.x() + (2 * uniform(rng) - 1) * 0.8 * radius;
    double v_root = lids.v_top_px - 0.1 * radius;
    if (lids.upper > 0) {  // the margin of Lids::Hides
      const double h = lids.v_bottom_px - lids.v_top_px, du = (u_root - lids.u_mid_px) / h;
      v_root = lids.v_top_px + lids.upper * h + 0.15 * h * du * du;
    }
    const double length = (0.35 + 0.35 * uniform(rng)) * radius;
    const double angle = (2 * uniform(rng) - 1) * 25.0 * M_PI / 180;  // from straight down
    const double bow = (2 * uniform(rng) - 1) * 0.25 * length;
    const double width = (0.02 + 0.03 * uniform(rng)) * radius;
    widest = std::max(widest, width);
    const Eigen::Vector2d root(u_root, v_root), tip = root + length * Eigen::Vector2d(std::sin(angle), std::cos(angle));
    const Eigen::Vector2d normal = Eigen::Vector2d(-(tip - root).y(), (tip - root).x()).normalized();
    std::vector<cv::Point> line;
    for (int i = 0; i <= 24; ++i) {
      const double t = i / 24.0;
      const Eigen::Vector2d p = (1 - t) * root + t * tip + 4 * t * (1 - t) * bow * normal;
      line.emplace_back(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
    }
    cv::polylines(mask, std::vector<std::vector<cv::Point>>{line}, false, cv::Scalar(255), std::max(1, static_cast<int>(std::lround(width))), cv::LINE_AA);
  }
  cv::Mat soft;
  mask.convertTo(soft, CV_32FC1, 1.0 / 255.0);
  cv::GaussianBlur(soft, soft, cv::Size(), 0.25 * widest);
  const float dark = static_cast<float>(1.0 - o.artefacts.lash_transmission);
  for (int v = 0; v < acc->rows; ++v) {
    float* a = acc->ptr<float>(v);
    const float* m = soft.ptr<float>(v);
    for (int u = 0; u < acc->cols; ++u) a[u] *= 1.0f - dark * std::min(1.0f, m[u]);
  }
}

}  // namespace

std::vector<SpotToRender> GrowDefocus(const std::vector<SpotToRender>& spots, const Lids& extent, double centre_px,
                                      double rim_px) {
  std::vector<SpotToRender> out = spots;
  const Eigen::Vector2d c = PatternCentre(extent);
  const double radius = PatternRadius(extent);
  if (!(radius > 0)) return out;
  for (auto& s : out) {
    if (s.id.ring == 0) continue;
    s.psf_sigma_px = centre_px + (rim_px - centre_px) * (s.centre_px - c).norm() / radius;
  }
  return out;
}

std::vector<SpotToRender> BreakTearFilm(const std::vector<SpotToRender>& spots, const Lids& extent, int patches,
                                        double psf_sigma_px, uint32_t seed) {
  std::mt19937 rng(seed ^ 0x7ea5u);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const Eigen::Vector2d c = PatternCentre(extent);
  const double radius = PatternRadius(extent);
  std::vector<std::pair<Eigen::Vector2d, double>> dry;
  for (int k = 0; k < patches; ++k) {
    const double rho = radius * std::sqrt(uniform(rng)), phi = 2 * M_PI * uniform(rng);
    dry.emplace_back(c + rho * Eigen::Vector2d(std::cos(phi), std::sin(phi)), (0.05 + 0.07 * uniform(rng)) * radius);
  }
  std::vector<SpotToRender> out;
  for (auto s : spots) {
    const bool inside = s.id.ring != 0 && std::any_of(dry.begin(), dry.end(), [&](const auto& d) {
                          return (s.centre_px - d.first).norm() < d.second;
                        });
    const double draw = uniform(rng);  // one draw per spot, inside or not: the rest of the pattern stays the same
    if (inside && draw < 0.5) continue;
    if (inside) {
      s.psf_sigma_px = 2.5 * (s.psf_sigma_px > 0 ? s.psf_sigma_px : psf_sigma_px);
      s.relative_brightness *= 0.5;
    }
    out.push_back(s);
  }
  return out;
}

bool SpotRenderOptions::IsValid(std::string* why) const {
  const auto fail = [why](std::string m) {
    if (why) *why = std::move(m);
    return false;
  };
  if (bits != 8 && bits != 16) return fail(fmt::format("bits must be 8 or 16 (got {})", bits));
  if (!(psf_sigma_px > 0) && shape == SpotShape::kPsf) return fail("psf_sigma_px must be > 0 for PSF spots");
  if (!(psf_sigma_px >= 0)) return fail("psf_sigma_px must be >= 0");
  const double full = bits == 8 ? 255.0 : 65535.0;
  if (!(background_dn >= 0) || !(peak_dn > 0) || background_dn + peak_dn > full) {
    return fail(fmt::format("background ({}) + peak ({}) must be within 0..{} DN", background_dn, peak_dn, full));
  }
  if (!(read_noise_dn >= 0) || !(gain_e_per_dn >= 0)) return fail("noise and gain must be >= 0");
  if (!(skin_dn >= 0) || !(skin_texture_dn >= 0) || background_dn + skin_dn > full) {
    return fail("the skin's level and texture must be >= 0 and the skin within the full scale");
  }
  if (!(lids.upper >= 0 && lids.upper < 1 && lids.lower >= 0 && lids.lower < 1)) return fail("lids must be in [0, 1)");
  const Artefacts& a = artefacts;
  if (a.lashes < 0 || !(a.lash_transmission >= 0 && a.lash_transmission <= 1)) {
    return fail("lashes must be >= 0 and their transmission in [0, 1]");
  }
  if (!(a.iris_dn >= 0) || background_dn + 2 * a.iris_dn > full) return fail("the iris must be >= 0 and within the full scale");
  if (!(a.motion_blur_px >= 0 && a.motion_blur_px <= 100) || !std::isfinite(a.motion_blur_deg)) {
    return fail("motion blur must be 0-100 px at a finite angle");
  }
  return true;
}

cv::Mat RenderSpotImage(const std::vector<SpotToRender>& spots, int width_px, int height_px,
                        const SpotRenderOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw util::InputError("RenderSpotImage: " + why);
  cv::Mat acc(height_px, width_px, CV_32FC1, cv::Scalar(0));
  for (const auto& s : spots) {
    const double sigma = s.psf_sigma_px > 0 ? s.psf_sigma_px : options.psf_sigma_px;
    const double peak = options.peak_dn * s.relative_brightness;
    if (options.shape == SpotShape::kPsf || s.id.ring == 0) {
      AddPsfSpot(s, sigma, peak, &acc);
    } else {
      AddEllipseSpot(s, sigma, peak, &acc);
    }
  }
  const Artefacts& art = options.artefacts;
  if (art.iris_dn > 0) AddIris(options, &acc);
  if (art.motion_blur_px > 0) MotionBlur(art, &acc);
  if (art.lashes > 0) ShadowLashes(options, &acc);
  if (options.lids.Any() && (options.skin_dn > 0 || options.skin_texture_dn > 0)) AddSkin(options, &acc);
  std::mt19937 rng(options.seed);
  std::normal_distribution<float> normal(0.f, 1.f);
  const double full = options.bits == 8 ? 255.0 : 65535.0;
  cv::Mat out(height_px, width_px, options.bits == 8 ? CV_8UC1 : CV_16UC1);
  for (int v = 0; v < height_px; ++v) {
    const float* a = acc.ptr<float>(v);
    for (int u = 0; u < width_px; ++u) {
      const double signal = std::min(a[u], static_cast<float>(full));
      double var = options.read_noise_dn * options.read_noise_dn;
      if (options.gain_e_per_dn > 0) var += signal / options.gain_e_per_dn;
      double value = options.background_dn + signal;
      if (var > 0) value += std::sqrt(var) * normal(rng);
      value = std::clamp(std::round(value), 0.0, full);
      if (options.bits == 8) {
        out.ptr<uint8_t>(v)[u] = static_cast<uint8_t>(value);
      } else {
        out.ptr<uint16_t>(v)[u] = static_cast<uint16_t>(value);
      }
    }
  }
  return out;
}

std::vector<SpotToRender> DropAndAddGlints(const std::vector<SpotToRender>& spots, double drop_fraction,
                                           int glint_count, double min_glint_distance_px, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<SpotToRender> out = spots;
  const int drop = static_cast<int>(std::round(std::clamp(drop_fraction, 0.0, 1.0) * spots.size()));
  std::shuffle(out.begin(), out.end(), rng);
  out.resize(out.size() - drop);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  if (spots.empty() || glint_count <= 0) return out;
  Eigen::Vector2d lo = spots[0].centre_px, hi = lo;
  for (const auto& s : spots) {
    lo = lo.cwiseMin(s.centre_px);
    hi = hi.cwiseMax(s.centre_px);
  }
  const Eigen::Vector2d grow = 0.2 * (hi - lo);
  std::uniform_real_distribution<double> ux(lo.x() - grow.x(), hi.x() + grow.x());
  std::uniform_real_distribution<double> uy(lo.y() - grow.y(), hi.y() + grow.y());
  std::uniform_real_distribution<double> size(1.0, 3.0), bright(0.5, 1.5);
  const double min2 = min_glint_distance_px * min_glint_distance_px;
  int placed = 0;
  for (int attempt = 0; attempt < 100000 && placed < glint_count; ++attempt) {
    const Eigen::Vector2d p(ux(rng), uy(rng));
    // Clear of every spot, dropped ones included (a glint exactly where a spot is missing would be that spot to
    // any detector), and of the glints already placed.
    bool clear = true;
    for (const auto& s : spots) clear = clear && (s.centre_px - p).squaredNorm() >= min2;
    for (const auto& s : out) clear = clear && (s.centre_px - p).squaredNorm() >= min2;
    if (!clear) continue;
    SpotToRender g;
    g.id = {0, placed++};
    g.centre_px = p;
    g.psf_sigma_px = size(rng);
    g.relative_brightness = bright(rng);
    out.push_back(g);
  }
  return out;
}

bool Lids::Hides(double u_px, double v_px) const {
  const double h = v_bottom_px - v_top_px;
  if (!(h > 0)) return false;
  const double du = (u_px - u_mid_px) / h;
  const double sag = 0.15 * h * du * du;  // the margin curves away from the pattern's centre
  return (upper > 0 && v_px < v_top_px + upper * h + sag) || (lower > 0 && v_px > v_bottom_px - lower * h - sag);
}

Lids LidsOver(const std::vector<SpotToRender>& spots, double upper, double lower) {
  Lids lids;
  lids.upper = upper;
  lids.lower = lower;
  if (spots.empty()) return lids;
  lids.v_top_px = lids.v_bottom_px = spots.front().centre_px.y();
  for (const auto& s : spots) {
    lids.v_top_px = std::min(lids.v_top_px, s.centre_px.y());
    lids.v_bottom_px = std::max(lids.v_bottom_px, s.centre_px.y());
    lids.u_mid_px += s.centre_px.x() / static_cast<double>(spots.size());
  }
  return lids;
}

std::vector<SpotToRender> HideUnderLids(const std::vector<SpotToRender>& spots, const Lids& lids) {
  std::vector<SpotToRender> out;
  for (const auto& s : spots) {
    if (!lids.Hides(s.centre_px.x(), s.centre_px.y())) out.push_back(s);
  }
  return out;
}

}  // namespace topocal::correct

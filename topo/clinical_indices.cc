#include "topo/clinical_indices.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <fmt/format.h>

#include "topo/sphere_fit.h"

namespace topocal::topo {
namespace {

bool Fail(std::string* why, std::string message) {
  if (why) *why = std::move(message);
  return false;
}

// Axial power at (rho, theta) by linear interpolation along the nearest meridian; NaN outside the samples.
double AxialAt(const PowerMaps& m, double rho_mm, double theta_deg) {
  int j = static_cast<int>(std::lround(theta_deg / 360.0 * m.meridians)) % m.meridians;
  if (j < 0) j += m.meridians;
  const double kf = rho_mm / m.radius_mm * m.radial_samples - 1.0;  // RhoMm(k) = R (k + 1) / K
  if (kf < 0 || kf > m.radial_samples - 1) return NAN;
  const int k0 = std::min(static_cast<int>(kf), m.radial_samples - 2);
  const double t = kf - k0;
  const double* row = &m.axial_D[static_cast<size_t>(j) * m.radial_samples];
  return (1 - t) * row[k0] + t * row[k0 + 1];
}

// sim-K (the ring's mean power on each meridian pair) and Kmax within the supported samples, with Kmax's second peak.
void SimKAndKmax(const PowerMaps& axial, const std::vector<int>& ring, int supported_samples, ClinicalIndices* ci) {
  const int M = axial.meridians, K = axial.radial_samples;
  // sim-K over the ring; meridian theta and theta + 180 together.
  std::vector<double> meridian_mean(M, 0.0);
  const int n_ring = static_cast<int>(ring.size());
  for (int j = 0; j < M; ++j) {
    const double* row = &axial.axial_D[static_cast<size_t>(j) * K];
    double sum = 0;
    for (const int k : ring) sum += row[k];
    meridian_mean[j] = sum / n_ring;
  }
  const auto opposite = [&](int j, double deg) { return (j + static_cast<int>(std::lround(deg / 360.0 * M))) % M; };
  int steep = 0;
  std::vector<double> pair(M);
  for (int j = 0; j < M; ++j) pair[j] = 0.5 * (meridian_mean[j] + meridian_mean[opposite(j, 180.0)]);
  for (int j = 0; j < M; ++j) if (pair[j] > pair[steep]) steep = j;
  const int flat = opposite(steep, 90.0);
  ci->steep_k_D = pair[steep];
  ci->flat_k_D = pair[flat];
  ci->steep_axis_deg = std::fmod(axial.ThetaDeg(steep), 180.0);
  ci->flat_axis_deg = std::fmod(axial.ThetaDeg(flat), 180.0);

  // Kmax within the supported radius.
  ci->kmax_D = -INFINITY;
  for (int j = 0; j < M; ++j) {
    for (int k = 0; k < supported_samples; ++k) {
      const double p = axial.axial_D[static_cast<size_t>(j) * K + k];
      if (p > ci->kmax_D) {
        ci->kmax_D = p;
        const double th = axial.ThetaDeg(j) * M_PI / 180.0;
        ci->kmax_at_mm = axial.RhoMm(k) * Eigen::Vector2d(std::cos(th), std::sin(th));
      }
    }
  }

  ci->kmax_runner_up_D = -INFINITY;
  for (int j = 0; j < M; ++j) {
    const double th = axial.ThetaDeg(j) * M_PI / 180.0;
    for (int k = 0; k < supported_samples; ++k) {
      const Eigen::Vector2d at = axial.RhoMm(k) * Eigen::Vector2d(std::cos(th), std::sin(th));
      if ((at - ci->kmax_at_mm).norm() >= kPeakSeparationMm) {
        ci->kmax_runner_up_D = std::max(ci->kmax_runner_up_D, axial.axial_D[static_cast<size_t>(j) * K + k]);
      }
    }
  }

}

// The elevation above the best-fit sphere `bfs` at the zone's points `pts`: rms, the peak (refined on a
// kElevationPeakStepMm grid) and its second peak, refined the same way.
template <typename OutsideZone>
void ElevationPeaks(const std::vector<Eigen::Vector3d>& pts, const SphereFit& bfs, const OutsideZone& outside_zone,
                    const SurfaceEvaluator& surface, double bfs_step_mm, ClinicalIndices* ci) {
  const double s[4] = {bfs.centre_mm.x(), bfs.centre_mm.y(), bfs.centre_mm.z(), bfs.radius_mm};
  ci->elevation_peak_um = -INFINITY;
  double sum2 = 0;
  for (const auto& p : pts) {
    const double dx = p.x() - s[0], dy = p.y() - s[1];
    const double zs = s[2] - std::sqrt(std::max(0.0, s[3] * s[3] - dx * dx - dy * dy));
    const double e_um = (zs - p.z()) * 1e3;  // in front of the sphere (towards the camera) is positive
    sum2 += e_um * e_um;
    if (e_um > ci->elevation_peak_um) {
      ci->elevation_peak_um = e_um;
      ci->elevation_peak_at_mm = p.head<2>();
    }
  }
  ci->elevation_rms_um = std::sqrt(sum2 / pts.size());
  // Refine the peak on a 0.01 mm grid around the best sample (within the zone).
  const auto elevation_at = [&](double x, double y, double* e_um) {
    model::SurfaceDerivatives d;
    const double dx = x - s[0], dy = y - s[1];
    if (outside_zone(x, y) || !surface(x, y, &d)) return false;
    *e_um = (s[2] - std::sqrt(std::max(0.0, s[3] * s[3] - dx * dx - dy * dy)) - d.z) * 1e3;
    return true;
  };
  // A coarse maximum refined on the fine grid around it (within the zone).
  const int fine = static_cast<int>(std::lround(bfs_step_mm / kElevationPeakStepMm));
  const auto refine = [&](const Eigen::Vector2d& coarse, double* value_um, Eigen::Vector2d* at_mm) {
    for (int iy = -fine; iy <= fine; ++iy) {
      for (int ix = -fine; ix <= fine; ++ix) {
        double e_um;
        const double x = coarse.x() + ix * kElevationPeakStepMm, y = coarse.y() + iy * kElevationPeakStepMm;
        if (elevation_at(x, y, &e_um) && e_um > *value_um) {
          *value_um = e_um;
          *at_mm = Eigen::Vector2d(x, y);
        }
      }
    }
  };
  refine(ci->elevation_peak_at_mm, &ci->elevation_peak_um, &ci->elevation_peak_at_mm);
  // The second peak: the highest sample kPeakSeparationMm or farther from the peak, refined the same way.
  ci->elevation_runner_up_um = -INFINITY;
  Eigen::Vector2d runner_up_at = Eigen::Vector2d::Zero();
  for (const auto& p : pts) {
    if ((p.head<2>() - ci->elevation_peak_at_mm).norm() < kPeakSeparationMm) continue;
    const double dx = p.x() - s[0], dy = p.y() - s[1];
    const double e_um = (s[2] - std::sqrt(std::max(0.0, s[3] * s[3] - dx * dx - dy * dy)) - p.z()) * 1e3;
    if (e_um > ci->elevation_runner_up_um) {
      ci->elevation_runner_up_um = e_um;
      runner_up_at = p.head<2>();
    }
  }
  if (std::isfinite(ci->elevation_runner_up_um)) refine(runner_up_at, &ci->elevation_runner_up_um, &runner_up_at);

}

}  // namespace

bool ComputeClinicalIndices(const PowerMaps& axial, const SurfaceEvaluator& surface, double supported_radius_mm,
                            const ClinicalOptions& o, ClinicalIndices* out, std::string* why) {
  ClinicalIndices ci;
  const int M = axial.meridians, K = axial.radial_samples;
  if (M < 4 || K < 2) return Fail(why, "clinical indices: the power map is empty");
  const double supported = std::min(supported_radius_mm, axial.radius_mm);
  ci.supported_radius_mm = supported;
  if (supported < o.sim_k_outer_mm) {
    return Fail(why, fmt::format("clinical indices: the data reach {:.2f} mm, less than the sim-K ring ({:.2f} mm)",
                                 supported, o.sim_k_outer_mm));
  }
  // The samples' radii are the same on every meridian: which of them lie in the sim-K ring, and how many lie
  // within the supported radius, is decided once (the same tests on the same RhoMm values as per sample).
  std::vector<int> ring;
  int supported_samples = 0;
  for (int k = 0; k < K; ++k) {
    const double rho = axial.RhoMm(k);
    if (!(rho < o.sim_k_inner_mm || rho > o.sim_k_outer_mm)) ring.push_back(k);
    if (supported_samples == k && rho <= supported) ++supported_samples;
  }
  if (ring.empty()) return Fail(why, "clinical indices: no power-map sample lies in the sim-K ring");
  SimKAndKmax(axial, ring, supported_samples, &ci);

  // Best-fit sphere over the zone: algebraic fit for the start, then the sag residual by Gauss-Newton (sphere_fit.h).
  const double zone = std::min(o.bfs_radius_mm, supported);
  ci.bfs_zone_radius_mm = zone;
  // std::hypot(x, y) > zone, with std::hypot (slow) called only near the rim: well inside it, x^2 + y^2 is below
  // zone^2 by far more than its rounding (and hypot's error of < 1 ulp), so the answer is the same.
  const double inside_for_sure_mm2 = zone * zone * (1.0 - 1e-9);
  const auto outside_zone = [&](double x, double y) {
    return !(x * x + y * y < inside_for_sure_mm2) && std::hypot(x, y) > zone;
  };
  std::vector<Eigen::Vector3d> pts;
  const int half = static_cast<int>(std::floor(zone / o.bfs_step_mm));
  for (int iy = -half; iy <= half; ++iy) {
    for (int ix = -half; ix <= half; ++ix) {
      const double x = ix * o.bfs_step_mm, y = iy * o.bfs_step_mm;
      if (outside_zone(x, y)) continue;
      model::SurfaceDerivatives d;
      if (!surface(x, y, &d)) return Fail(why, fmt::format("clinical indices: the surface is undefined at ({:.2f}, {:.2f}) mm", x, y));
      pts.emplace_back(x, y, d.z);
    }
  }
  if (pts.size() < 10) return Fail(why, "clinical indices: too few points for the best-fit sphere");
  // The sphere's one owner (topo/sphere_fit.h), with the sag residual: elevation is read along the axis.
  SphereFitOptions sphere_options;
  sphere_options.residual = SphereResidual::kSag;
  sphere_options.stddev = false;
  const SphereFit bfs = FitSphere(pts, sphere_options);
  if (!bfs.ok) return Fail(why, fmt::format("clinical indices: best-fit sphere failed: {}", bfs.message));
  ci.bfs_centre_mm = bfs.centre_mm;
  ci.bfs_radius_mm = bfs.radius_mm;
  ElevationPeaks(pts, bfs, outside_zone, surface, o.bfs_step_mm, &ci);

  // I-S at is_radius_mm.
  if (o.is_radius_mm <= supported) {
    double inf = 0, sup = 0;
    for (int i = 0; i < 5; ++i) {
      inf += AxialAt(axial, o.is_radius_mm, 210.0 + 30.0 * i);
      sup += AxialAt(axial, o.is_radius_mm, 30.0 + 30.0 * i);
    }
    ci.inferior_superior_D = (inf - sup) / 5.0;
    ci.is_available = std::isfinite(ci.inferior_superior_D);
    if (!ci.is_available) ci.inferior_superior_D = 0;
  }
  *out = ci;
  return true;
}

}  // namespace topocal::topo

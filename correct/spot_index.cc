#include "correct/spot_index.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <Eigen/Dense>
#include <fmt/format.h>

namespace topocal::correct {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// A bivariate polynomial map R^2 -> R^2 of total degree <= d in t = q / scale (scaled for conditioning).
// Written here because the deformation is a tiny linear least-squares problem (<= 21 terms) solved by Eigen.
class PolynomialMap {
 public:
  PolynomialMap() = default;
  PolynomialMap(int degree, double scale) : degree_(degree), scale_(scale) {}

  static constexpr int kMaxDegree = 5;
  static int Terms(int degree) { return (degree + 1) * (degree + 2) / 2; }
  int degree() const { return degree_; }

  void Monomials(const Eigen::Vector2d& q, double* out) const {
    const double x = q.x() / scale_, y = q.y() / scale_;
    double px[kMaxDegree + 1], py[kMaxDegree + 1];
    px[0] = py[0] = 1.0;
    for (int i = 1; i <= degree_; ++i) {
      px[i] = px[i - 1] * x;
      py[i] = py[i - 1] * y;
    }
    int k = 0;
    for (int d = 0; d <= degree_; ++d) {
      for (int j = 0; j <= d; ++j) out[k++] = px[d - j] * py[j];
    }
  }
  Eigen::Vector2d operator()(const Eigen::Vector2d& q) const {
    double m[32] = {};  // Monomials fills the first Terms(degree_) entries; zeroed to keep -Wmaybe-uninitialized quiet
    Monomials(q, m);
    Eigen::Vector2d p = Eigen::Vector2d::Zero();
    for (int k = 0; k < coef_.rows(); ++k) p += m[k] * coef_.row(k).transpose();
    return p;
  }
  // Smallest singular value of the Jacobian at q: the local scale by which spacings shrink at worst.
  double MinScale(const Eigen::Vector2d& q) const {
    const double h = 1e-4 * scale_;
    Eigen::Matrix2d j;
    j.col(0) = ((*this)(q + Eigen::Vector2d(h, 0)) - (*this)(q - Eigen::Vector2d(h, 0))) / (2 * h);
    j.col(1) = ((*this)(q + Eigen::Vector2d(0, h)) - (*this)(q - Eigen::Vector2d(0, h))) / (2 * h);
    return Eigen::JacobiSVD<Eigen::Matrix2d>(j).singularValues()(1);
  }
  bool Fit(const std::vector<Eigen::Vector2d>& q, const std::vector<Eigen::Vector2d>& p) {
    const int n = static_cast<int>(q.size()), t = Terms(degree_);
    if (n < t) return false;
    Eigen::MatrixXd a(n, t), b(n, 2);
    for (int i = 0; i < n; ++i) {
      double m[32];
      Monomials(q[i], m);
      for (int k = 0; k < t; ++k) a(i, k) = m[k];
      b.row(i) = p[i].transpose();
    }
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
    if (qr.rank() < t) return false;
    coef_ = qr.solve(b);
    return coef_.allFinite();
  }
  void SetAffine(const Eigen::Vector2d& offset, const Eigen::Matrix2d& linear) {
    degree_ = 1;
    coef_.resize(3, 2);
    coef_.row(0) = offset.transpose();
    coef_.row(1) = scale_ * linear.col(0).transpose();  // coefficient of x / scale
    coef_.row(2) = scale_ * linear.col(1).transpose();
  }

 private:
  int degree_ = 1;
  double scale_ = 1;
  Eigen::MatrixXd coef_;  // Terms x 2
};

Eigen::Matrix2d SqrtSym(const Eigen::Matrix2d& m) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(m);
  return es.eigenvectors() * es.eigenvalues().cwiseMax(0).cwiseSqrt().asDiagonal() * es.eigenvectors().transpose();
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t k = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

struct Template {
  std::vector<model::IdealSpot> spots;
  std::vector<std::vector<int>> rings;  // indices into spots, per ring (0-based ring number)
  std::vector<double> spacing;          // per spot: min(arc, ring) spacing in the ideal image, mm
};

Template MakeTemplate(const model::IdealImageParams& ideal) {
  Template t;
  t.spots = model::IdealImage(ideal);
  const int n_rings = ideal.rings_N + 1;
  t.rings.resize(n_rings);
  const double ring_step = model::RingStepMm(ideal);
  for (int i = 0; i < static_cast<int>(t.spots.size()); ++i) {
    const auto& s = t.spots[i];
    t.rings[s.id.ring - 1].push_back(i);
    const int per_ring = model::SpotsOnRing(ideal, s.id.ring);
    const double arc = 2.0 * M_PI * s.position_mm.norm() / per_ring;
    t.spacing.push_back(std::min(arc, ring_step));
  }
  return t;
}

// The start's centre, moved to where the two innermost rings are. On a misaligned device (a tilted cone, a decentred
// screen or principal point) the rings are not concentric: the inner rings' centre sits up to a ring spacing or
// more from the moments' centre (a 1.5 deg tilt: ~0.8 spacings), beyond the growth's gate, and ring 1 would be
// lost. Score each candidate offset on a grid over a disc of `search_radius` by the truncated squared distances
// from the predicted spots of rings 1 and 2 to their nearest detections; take the best.
Eigen::Vector2d InnerRingsCentre(const std::vector<Eigen::Vector2d>& det, const Template& tpl,
                                 const Eigen::Vector2d& mu, const Eigen::Matrix2d& a0, double search_radius,
                                 double step, double gate) {
  std::vector<Eigen::Vector2d> q;
  for (int r = 0; r < std::min<int>(2, tpl.rings.size()); ++r) {
    for (const int j : tpl.rings[r]) q.push_back(a0 * tpl.spots[j].position_mm);
  }
  double reach = 0;
  for (const auto& v : q) reach = std::max(reach, v.norm());
  // Only detections that a candidate's prediction could reach.
  std::vector<Eigen::Vector2d> near;
  for (const auto& p : det) {
    if ((p - mu).norm() <= search_radius + reach + gate) near.push_back(p);
  }
  const double gate2 = gate * gate;
  const auto score = [&](const Eigen::Vector2d& c) {
    double sum = 0;
    for (const auto& v : q) {
      double best = gate2;
      for (const auto& p : near) best = std::min(best, (p - c - v).squaredNorm());
      sum += best;
    }
    return sum;
  };
  Eigen::Vector2d best_c = mu;
  double best = score(mu);
  const int n = static_cast<int>(std::ceil(search_radius / step));
  for (int iy = -n; iy <= n; ++iy) {
    for (int ix = -n; ix <= n; ++ix) {
      const Eigen::Vector2d off(ix * step, iy * step);
      if (off.norm() > search_radius) continue;
      const double sc = score(mu + off);
      if (sc < best) {
        best = sc;
        best_c = mu + off;
      }
    }
  }
  return best_c;
}

}  // namespace

bool IndexingOptions::IsValid(std::string* why) const {
  const auto fail = [why](std::string m) {
    if (why) *why = std::move(m);
    return false;
  };
  if (!(gate_fraction > 0 && gate_fraction < 0.5)) return fail("gate_fraction must be in (0, 0.5)");
  if (!(residual_gate_sigmas > 0)) return fail("residual_gate_sigmas must be > 0");
  if (!(residual_gate_floor_fraction > 0 && residual_gate_floor_fraction <= gate_fraction)) {
    return fail("residual_gate_floor_fraction must be in (0, gate_fraction]");
  }
  if (final_passes < 1) return fail("final_passes must be >= 1");
  return true;
}

SpotIndexing IndexSpots(const std::vector<Eigen::Vector2d>& det, const model::IdealImageParams& ideal,
                        const IndexingOptions& options) {
  SpotIndexing out;
  std::string why;
  if (!options.IsValid(&why)) {
    out.message = "invalid options: " + why;
    return out;
  }
  const Template tpl = MakeTemplate(ideal);
  const int n_det = static_cast<int>(det.size());
  const int n_tpl = static_cast<int>(tpl.spots.size());
  constexpr int kMinDetections = 8;  // fewer than one ring: nothing to anchor the pattern on
  if (n_det < kMinDetections) {
    out.message = fmt::format("{} detections: too few to index (need >= {})", n_det, kMinDetections);
    for (int i = 0; i < n_det; ++i) out.unassigned_detections.push_back(i);
    for (const auto& s : tpl.spots) out.missing.push_back(s.id);
    return out;
  }
  const double rho_n = ideal.rhoN_mm;

  // 1. Start: moments, trimmed. The ideal image's covariance is isotropic: (mean rho^2 / 2) I.
  double mean_rho2 = 0;
  for (const auto& s : tpl.spots) mean_rho2 += s.position_mm.squaredNorm();
  mean_rho2 /= n_tpl;
  const double tpl_var = mean_rho2 / 2.0;
  std::vector<double> xs, ys;
  for (const auto& p : det) {
    xs.push_back(p.x());
    ys.push_back(p.y());
  }
  Eigen::Vector2d mu(Median(xs), Median(ys));
  Eigen::Matrix2d a0 = Eigen::Matrix2d::Identity();
  std::vector<bool> keep(n_det);
  for (int it = 0; it < 4; ++it) {
    const Eigen::Matrix2d a0_inv = a0.inverse();
    // First pass: a generous disc of twice the design radius; then the normalised pattern plus a 20 % margin.
    const double limit = it == 0 ? 2.0 * rho_n : 1.2 * rho_n;
    int kept = 0;
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    for (int i = 0; i < n_det; ++i) {
      keep[i] = (a0_inv * (det[i] - mu)).norm() < limit;
      if (keep[i]) {
        sum += det[i];
        ++kept;
      }
    }
    if (kept < kMinDetections) {
      out.message = "the detections do not form a compact pattern";
      break;
    }
    mu = sum / kept;
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (int i = 0; i < n_det; ++i) {
      if (keep[i]) cov += (det[i] - mu) * (det[i] - mu).transpose();
    }
    cov /= kept;
    a0 = SqrtSym(cov) / std::sqrt(tpl_var);
    if (!(a0.determinant() > 0) || !a0.allFinite()) {
      out.message = "the detections are degenerate (collinear or coincident)";
      break;
    }
  }
  if (!out.message.empty()) {
    for (int i = 0; i < n_det; ++i) out.unassigned_detections.push_back(i);
    for (const auto& s : tpl.spots) out.missing.push_back(s.id);
    return out;
  }
  {
    // Ring spacing and ring 1's arc spacing as the start maps them (detection units).
    const double scale = std::sqrt(a0.determinant());
    const double ring_step = model::RingStepMm(ideal) * scale;
    const double inner_spacing = tpl.spacing[tpl.rings[0].front()] * scale;
    mu = InnerRingsCentre(det, tpl, mu, a0, 2.0 * ring_step, inner_spacing / 8.0, options.gate_fraction * inner_spacing);
  }
  PolynomialMap map(1, rho_n);
  map.SetAffine(mu, a0);

  std::vector<int> det_of_tpl(n_tpl, -1), tpl_of_det(n_det, -1);
  const auto refit = [&](int degree) {
    std::vector<Eigen::Vector2d> q, p;
    for (int j = 0; j < n_tpl; ++j) {
      if (det_of_tpl[j] >= 0) {
        q.push_back(tpl.spots[j].position_mm);
        p.push_back(det[det_of_tpl[j]]);
      }
    }
    for (int d = std::min(degree, PolynomialMap::kMaxDegree); d >= 1; d -= 2) {
      PolynomialMap m(d, rho_n);
      if (m.Fit(q, p)) {
        map = m;
        return;
      }
    }
  };
  const auto assign = [&](int j, int i) {
    det_of_tpl[j] = i;
    tpl_of_det[i] = j;
  };
  const auto unassign_all = [&] {
    std::fill(det_of_tpl.begin(), det_of_tpl.end(), -1);
    std::fill(tpl_of_det.begin(), tpl_of_det.end(), -1);
  };

  // 2. Growth, ring by ring.
  const int n_rings = static_cast<int>(tpl.rings.size());
  for (int k = 0; k < n_rings; ++k) {
    std::vector<Eigen::Vector2d> pred(n_tpl);
    const int r_lo = std::max(0, k - 1), r_hi = std::min(n_rings - 1, k + 1);
    for (int r = r_lo; r <= r_hi; ++r) {
      for (const int j : tpl.rings[r]) pred[j] = map(tpl.spots[j].position_mm);
    }
    // Candidate pairs (distance, template, detection) of this ring within the gate.
    struct Pair {
      double d;
      int j, i;
    };
    std::vector<Pair> pairs;
    for (const int j : tpl.rings[k]) {
      const double gate = options.gate_fraction * tpl.spacing[j] * map.MinScale(tpl.spots[j].position_mm);
      int best = -1;
      double best_d = kInf;
      for (int i = 0; i < n_det; ++i) {
        if (tpl_of_det[i] >= 0) continue;
        const double d = (det[i] - pred[j]).norm();
        if (d < best_d) {
          best_d = d;
          best = i;
        }
      }
      if (best < 0 || best_d > gate) continue;
      // The detection must not be closer to a spot of this or a neighbouring ring than to j.
      bool nearest = true;
      for (int r = r_lo; r <= r_hi && nearest; ++r) {
        for (const int jj : tpl.rings[r]) {
          if (jj != j && (det[best] - pred[jj]).norm() < best_d) {
            nearest = false;
            break;
          }
        }
      }
      if (nearest) pairs.push_back({best_d, j, best});
    }
    std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.d < b.d; });
    for (const auto& pr : pairs) {
      if (tpl_of_det[pr.i] < 0 && det_of_tpl[pr.j] < 0) assign(pr.j, pr.i);
    }
    const int rings_known = k + 1;
    refit(rings_known <= 2 ? 1 : rings_known < 6 ? 3 : 5);
  }

  // 3. Final passes: global mutual-nearest assignment against the full fit.
  double res_scale = kInf;
  for (int pass = 0; pass < options.final_passes; ++pass) {
    std::vector<double> res;
    for (int j = 0; j < n_tpl; ++j) {
      if (det_of_tpl[j] >= 0) res.push_back((det[det_of_tpl[j]] - map(tpl.spots[j].position_mm)).norm());
    }
    res_scale = 1.4826 * Median(res);
    std::vector<Eigen::Vector2d> pred(n_tpl);
    std::vector<double> gate(n_tpl);
    for (int j = 0; j < n_tpl; ++j) {
      pred[j] = map(tpl.spots[j].position_mm);
      const double spacing = tpl.spacing[j] * map.MinScale(tpl.spots[j].position_mm);
      gate[j] = std::min(options.gate_fraction * spacing,
                         std::max(options.residual_gate_sigmas * res_scale,
                                  options.residual_gate_floor_fraction * spacing));
    }
    std::vector<int> nearest_tpl(n_det, -1), nearest_det(n_tpl, -1);
    std::vector<double> d_tpl(n_det, kInf), d_det(n_tpl, kInf);
    for (int i = 0; i < n_det; ++i) {
      for (int j = 0; j < n_tpl; ++j) {
        const double d = (det[i] - pred[j]).squaredNorm();
        if (d < d_tpl[i]) {
          d_tpl[i] = d;
          nearest_tpl[i] = j;
        }
        if (d < d_det[j]) {
          d_det[j] = d;
          nearest_det[j] = i;
        }
      }
    }
    unassign_all();
    for (int j = 0; j < n_tpl; ++j) {
      const int i = nearest_det[j];
      if (i >= 0 && nearest_tpl[i] == j && std::sqrt(d_det[j]) <= gate[j]) assign(j, i);
    }
    refit(5);
  }

  // Result.
  std::vector<double> res;
  for (int j = 0; j < n_tpl; ++j) {
    if (det_of_tpl[j] < 0) {
      out.missing.push_back(tpl.spots[j].id);
      continue;
    }
    IndexedSpot s;
    s.id = tpl.spots[j].id;
    s.detection = det_of_tpl[j];
    s.position = det[s.detection];
    s.residual = (s.position - map(tpl.spots[j].position_mm)).norm();
    res.push_back(s.residual * s.residual);
    out.spots.push_back(s);
  }
  std::sort(out.spots.begin(), out.spots.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  for (int i = 0; i < n_det; ++i) {
    if (tpl_of_det[i] < 0) out.unassigned_detections.push_back(i);
  }
  out.residual_rms = res.empty() ? 0 : std::sqrt(std::accumulate(res.begin(), res.end(), 0.0) / res.size());
  out.polynomial_degree = map.degree();
  out.ok = !out.spots.empty();
  out.message = fmt::format("{} of {} designed spots indexed, {} missing, {} detections unassigned",
                            out.spots.size(), n_tpl, out.missing.size(), out.unassigned_detections.size());
  return out;
}

}  // namespace topocal::correct

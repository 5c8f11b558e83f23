#include "pipeline/harness_answer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>

namespace topocal::pipeline {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// What a residual field looks like: cases with the same key differ only in the size of their residual.
using GroupKey = std::tuple<int, int, int, double, int>;  // cornea, family, orientation, noise, draw

struct Crossing {
  double residual_um = kInf;
  int failing_case = -1;
};

// The worst zero-residual case of a cornea and noise level.
struct Anchor {
  double u = 0;
  int index = -1;
};

// First crossing of u = 1 along a group sorted by residual, starting from the anchor (0, u0). An anchor already
// outside the limits is the crossing itself, at zero residual.
Crossing GroupCrossing(const std::vector<const HarnessCaseResult*>& group, const Anchor& anchor,
                       const HarnessLimits& limits) {
  Crossing c;
  if (anchor.u > 1) return {0.0, anchor.index};
  double r_prev = 0, u_prev = anchor.u;
  for (const auto* m : group) {
    const double u = LimitUtilisation(*m, limits);
    if (u <= 1) {
      r_prev = m->residual_max_um;
      u_prev = u;
      continue;
    }
    c.failing_case = m->spec.index;
    if (std::isinf(u) || u <= u_prev) {
      c.residual_um = r_prev;
    } else {
      c.residual_um = r_prev + (1.0 - u_prev) / (u - u_prev) * (m->residual_max_um - r_prev);
    }
    return c;
  }
  return c;
}

}  // namespace

double LimitUtilisation(const HarnessCaseResult& c, const HarnessLimits& limits) {
  if (!c.ok) return kInf;
  return std::max(c.MaxAbsDk() / limits.dk, c.MaxAbsDP_D(limits) / limits.dP_D);
}

InverseAnswer ComputeInverseAnswer(const HarnessRun& run) {
  const HarnessLimits& limits = run.config.limits;
  InverseAnswer a;
  std::map<std::pair<int, double>, Anchor> anchor;  // (cornea, noise) -> worst case without residual
  std::map<GroupKey, std::vector<const HarnessCaseResult*>> groups;
  for (const auto& c : run.cases) {
    const double u = LimitUtilisation(c, limits);
    if (!c.ok) ++a.cases_failed;
    (u <= 1 ? a.cases_within : a.cases_outside) += 1;
    a.max_tested_um = std::max(a.max_tested_um, c.residual_max_um);
    if (c.residual_max_um <= kZeroResidualUm) {
      auto& w = anchor[{c.spec.cornea, c.spec.noise_px}];
      if (w.index < 0 || u > w.u) w = {u, c.spec.index};
      continue;
    }
    const double orientation = -c.spec.calibration_error * c.spec.coefficient;
    groups[{c.spec.cornea, static_cast<int>(c.spec.family), orientation > 0 ? 1 : -1, c.spec.noise_px, c.spec.draw}]
        .push_back(&c);
  }
  // Grid bounds, independent of any interpolation.
  a.grid_first_failure_um = kInf;
  for (const auto& c : run.cases) {
    if (LimitUtilisation(c, limits) > 1) a.grid_first_failure_um = std::min(a.grid_first_failure_um, c.residual_max_um);
  }
  for (const auto& c : run.cases) {
    if (c.residual_max_um < a.grid_first_failure_um) {
      a.grid_all_pass_up_to_um = std::max(a.grid_all_pass_up_to_um, c.residual_max_um);
    }
  }
  for (const auto& [key, w] : anchor) {
    if (w.u > 1) a.noise_alone_exceeds = true;
  }

  Crossing best;
  std::map<int, Crossing> by_family;
  std::map<int, double> family_max_um;
  for (auto& [key, members] : groups) {
    std::sort(members.begin(), members.end(), [](const HarnessCaseResult* x, const HarnessCaseResult* y) {
      return x->residual_max_um != y->residual_max_um ? x->residual_max_um < y->residual_max_um
                                                      : x->spec.index < y->spec.index;
    });
    const auto it = anchor.find({std::get<0>(key), std::get<3>(key)});
    const Crossing c = GroupCrossing(members, it == anchor.end() ? Anchor{} : it->second, limits);
    const int family = std::get<1>(key);
    family_max_um[family] = std::max(family_max_um[family], members.back()->residual_max_um);
    auto better = [](const Crossing& x, const Crossing& y) {
      return x.residual_um != y.residual_um ? x.residual_um < y.residual_um : x.failing_case < y.failing_case;
    };
    if (c.failing_case >= 0 && (best.failing_case < 0 || better(c, best))) best = c;
    auto& f = by_family[family];
    if (c.failing_case >= 0 && (f.failing_case < 0 || better(c, f))) f = c;
  }
  // A zero-residual case outside the limits whose cornea and noise level have no group (only zero coefficients
  // or e = 0 swept).
  for (const auto& [key, w] : anchor) {
    if (w.u > 1 && (best.failing_case < 0 || best.residual_um > 0)) best = {0.0, w.index};
  }
  if (best.failing_case >= 0) {
    a.found = true;
    a.residual_max_um = best.residual_um;
    a.limiting_case = best.failing_case;
    const auto& lc = run.cases[static_cast<size_t>(best.failing_case)];
    a.limited_by = !lc.ok ? "failure" : (lc.MaxAbsDk() / limits.dk >= lc.MaxAbsDP_D(limits) / limits.dP_D ? "dk" : "dP");
  } else {
    a.residual_max_um = a.max_tested_um;
    a.grid_first_failure_um = 0;
    a.grid_all_pass_up_to_um = a.max_tested_um;
  }
  a.residual_max_px = a.residual_max_um / run.config.pixel_pitch_um;
  if (!run.truth.empty() && run.truth.front().spot_field_radius_mm > 0) {
    const double r = run.truth.front().spot_field_radius_mm;
    const double m = std::abs(run.config.design.distortion.magnification);
    // Seidel displacement at radius r: |sigma / M_T^3| r^3 (paper Eq. 18).
    a.sigma_equivalent_per_mm2 = a.residual_max_um * 1e-3 * m * m * m / (r * r * r);
  }
  for (const DistortionFamily f : kDistortionFamilies) {
    if (run.config.Coefficients(f).empty()) continue;
    FamilyAnswer fa;
    fa.family = f;
    const auto it = by_family.find(static_cast<int>(f));
    if (it != by_family.end()) {
      fa.found = true;
      fa.residual_max_um = it->second.residual_um;
    } else {
      fa.residual_max_um = family_max_um[static_cast<int>(f)];
    }
    a.families.push_back(fa);
  }
  return a;
}

}  // namespace topocal::pipeline

#include "harness/harness_answer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>

namespace topocal::harness {
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

// A case of a group with its abscissa: the residual (um) of a distortion case, |error| of an assembly case.
struct Member {
  double x = 0;
  const HarnessCaseResult* c = nullptr;
};

// First crossing of u = 1 along a group sorted by x, starting from the anchor (0, u0). An anchor already outside
// the limits is the crossing itself, at zero.
Crossing GroupCrossing(const std::vector<Member>& group, const Anchor& anchor, const HarnessLimits& limits) {
  Crossing c;
  if (anchor.u > 1) return {0.0, anchor.index};
  double r_prev = 0, u_prev = anchor.u;
  for (const auto& m : group) {
    const double u = LimitUtilisation(*m.c, limits);
    if (u <= 1) {
      r_prev = m.x;
      u_prev = u;
      continue;
    }
    c.failing_case = m.c->spec.index;
    if (std::isinf(u) || u <= u_prev) {
      c.residual_um = r_prev;
    } else {
      c.residual_um = r_prev + (1.0 - u_prev) / (u - u_prev) * (m.x - r_prev);
    }
    return c;
  }
  return c;
}

void SortByX(std::vector<Member>* members) {
  std::sort(members->begin(), members->end(), [](const Member& x, const Member& y) {
    return x.x != y.x ? x.x < y.x : x.c->spec.index < y.c->spec.index;
  });
}

bool Better(const Crossing& x, const Crossing& y) {
  return x.residual_um != y.residual_um ? x.residual_um < y.residual_um : x.failing_case < y.failing_case;
}

std::string LimitedBy(const HarnessCaseResult& c, const HarnessLimits& limits) {
  return !c.ok ? "failure" : (c.MaxAbsDk() / limits.dk >= c.MaxAbsDP_D(limits) / limits.dP_D ? "dk" : "dP");
}

AssemblyAnswer AxisAnswer(const HarnessRun& run, AssemblyAxis axis) {
  const HarnessLimits& limits = run.config.limits;
  AssemblyAnswer a;
  a.axis = axis;
  // Zero-error cases are the nominal device: the anchor of every group of the cornea and noise level.
  std::map<std::pair<int, double>, Anchor> anchor;
  // cornea, direction (sign, azimuth), noise, draw
  std::map<std::tuple<int, int, double, double, int>, std::vector<Member>> groups;
  std::vector<const HarnessCaseResult*> mine;
  for (const auto& c : run.cases) {
    if (c.spec.kind != HarnessCaseKind::kAssembly) continue;
    const double u = LimitUtilisation(c, limits);
    if (c.spec.error == 0) {
      auto& w = anchor[{c.spec.cornea, c.spec.noise_px}];
      if (w.index < 0 || u > w.u) w = {u, c.spec.index};
    }
    if (c.spec.axis != axis) continue;
    mine.push_back(&c);
    a.max_tested = std::max(a.max_tested, std::abs(c.spec.error));
    if (c.spec.error == 0) continue;
    groups[{c.spec.cornea, c.spec.error > 0 ? 1 : -1, c.spec.azimuth_deg, c.spec.noise_px, c.spec.draw}].push_back(
        {std::abs(c.spec.error), &c});
  }
  a.grid_first_failure = kInf;
  for (const auto* c : mine) {
    if (LimitUtilisation(*c, limits) > 1)
      a.grid_first_failure = std::min(a.grid_first_failure, std::abs(c->spec.error));
  }
  for (const auto* c : mine) {
    if (std::abs(c->spec.error) < a.grid_first_failure) {
      a.grid_all_pass_up_to = std::max(a.grid_all_pass_up_to, std::abs(c->spec.error));
    }
  }
  Crossing best;
  for (auto& [key, members] : groups) {
    SortByX(&members);
    const auto it = anchor.find({std::get<0>(key), std::get<3>(key)});
    const Crossing c = GroupCrossing(members, it == anchor.end() ? Anchor{} : it->second, limits);
    if (c.failing_case >= 0 && (best.failing_case < 0 || Better(c, best))) best = c;
  }
  // A zero-error case of this axis outside the limits (an axis swept at 0 only has no group).
  for (const auto* c : mine) {
    if (c->spec.error == 0 && LimitUtilisation(*c, limits) > 1 && (best.failing_case < 0 || best.residual_um > 0)) {
      best = {0.0, c->spec.index};
    }
  }
  if (best.failing_case >= 0) {
    a.found = true;
    a.max_error = best.residual_um;
    a.limiting_case = best.failing_case;
    const auto& lc = run.cases[static_cast<size_t>(best.failing_case)];
    a.noise_alone_exceeds = lc.spec.kind == HarnessCaseKind::kAssembly && lc.spec.error == 0;
    a.limited_by = LimitedBy(lc, limits);
  } else {
    a.max_error = a.max_tested;
    a.grid_first_failure = 0;
    a.grid_all_pass_up_to = a.max_tested;
  }
  return a;
}

}  // namespace

double LimitUtilisation(const HarnessCaseResult& c, const HarnessLimits& limits) {
  if (!c.ok) return kInf;
  return std::max(c.MaxAbsDk() / limits.dk, c.MaxAbsDP_D(limits) / limits.dP_D);
}

namespace {

// Grid bounds, independent of any interpolation: the smallest residual of a distortion case outside the limits, and
// the largest below it.
void SetGridBounds(const HarnessRun& run, InverseAnswer* a) {
  a->grid_first_failure_um = kInf;
  for (const auto& c : run.cases) {
    if (c.spec.kind == HarnessCaseKind::kDistortion && LimitUtilisation(c, run.config.limits) > 1) {
      a->grid_first_failure_um = std::min(a->grid_first_failure_um, c.residual_max_um);
    }
  }
  for (const auto& c : run.cases) {
    if (c.spec.kind == HarnessCaseKind::kDistortion && c.residual_max_um < a->grid_first_failure_um) {
      a->grid_all_pass_up_to_um = std::max(a->grid_all_pass_up_to_um, c.residual_max_um);
    }
  }
}

}  // namespace

InverseAnswer ComputeInverseAnswer(const HarnessRun& run) {
  const HarnessLimits& limits = run.config.limits;
  InverseAnswer a;
  std::map<std::pair<int, double>, Anchor> anchor;  // (cornea, noise) -> worst case without residual
  std::map<GroupKey, std::vector<Member>> groups;
  for (const auto& c : run.cases) {
    const double u = LimitUtilisation(c, limits);
    if (!c.ok) ++a.cases_failed;
    (u <= 1 ? a.cases_within : a.cases_outside) += 1;
    if (c.spec.kind != HarnessCaseKind::kDistortion) continue;
    a.max_tested_um = std::max(a.max_tested_um, c.residual_max_um);
    if (c.residual_max_um <= kZeroResidualUm) {
      auto& w = anchor[{c.spec.cornea, c.spec.noise_px}];
      if (w.index < 0 || u > w.u) w = {u, c.spec.index};
      continue;
    }
    const double orientation = -c.spec.calibration_error * c.spec.coefficient;
    groups[{c.spec.cornea, static_cast<int>(c.spec.family), orientation > 0 ? 1 : -1, c.spec.noise_px, c.spec.draw}]
        .push_back({c.residual_max_um, &c});
  }
  SetGridBounds(run, &a);
  for (const auto& [key, w] : anchor) {
    if (w.u > 1) a.noise_alone_exceeds = true;
  }

  Crossing best;
  std::map<int, Crossing> by_family;
  std::map<int, double> family_max_um;
  for (auto& [key, members] : groups) {
    SortByX(&members);
    const auto it = anchor.find({std::get<0>(key), std::get<3>(key)});
    const Crossing c = GroupCrossing(members, it == anchor.end() ? Anchor{} : it->second, limits);
    const int family = std::get<1>(key);
    family_max_um[family] = std::max(family_max_um[family], members.back().x);
    if (c.failing_case >= 0 && (best.failing_case < 0 || Better(c, best))) best = c;
    if (c.failing_case < 0) continue;  // within the limits throughout: no crossing (operator[] made one at +inf)
    auto& f = by_family[family];
    if (f.failing_case < 0 || Better(c, f)) f = c;
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
    a.limited_by = LimitedBy(lc, limits);
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
  for (const AssemblyAxis axis : kAssemblyAxes) {
    if (!run.config.Errors(axis).empty()) a.assembly.push_back(AxisAnswer(run, axis));
  }
  return a;
}

}  // namespace topocal::harness

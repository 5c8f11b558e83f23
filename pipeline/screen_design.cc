// The search of `topocal design --optimize` (pipeline/screen_design.h, docs/screen-design.md).
#include "pipeline/screen_design.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <tuple>
#include <stdexcept>

#include "correct/spot_index.h"
#include "model/freeform_test_set.h"
#include "model/null_screen.h"
#include "model/null_screen_layout.h"
#include "plot/null_screen_svg.h"
#include "topo/truth_comparison.h"
#include "util/parallel.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Each spot is paired with its nearest designed neighbours (ideal image): the closest approach of two spot images
// is always between near neighbours, and six hold a spot's ring and the two rings beside it.
constexpr int kNeighbours = 6;
// The resolving range's limits are found to this (bisection; far below the 0.25 D ~ 0.05 mm a clinician reads).
constexpr double kResolveToleranceMm = 0.005;
// Steps of the scan towards flat corneas (the spacing grows with the apex radius: only a ray that misses ends it).
constexpr double kFlatScanStepMm = 0.5;

struct Pair {
  size_t a, b;
  double ideal_um;  // centre distance on the ideal image
};

// Each spot's kNeighbours nearest spots of the ideal image, each pair once. Brute force: 2,000 spots are 4e6
// distances, a few ms, once per candidate.
std::vector<Pair> NeighbourPairs(const std::vector<model::TargetPoint>& targets) {
  std::vector<Pair> pairs;
  std::vector<std::pair<double, size_t>> d(targets.size());
  for (size_t i = 0; i < targets.size(); ++i) {
    for (size_t j = 0; j < targets.size(); ++j) d[j] = {(targets[j].ideal_mm - targets[i].ideal_mm).norm(), j};
    const size_t k = std::min<size_t>(kNeighbours + 1, d.size());
    std::partial_sort(d.begin(), d.begin() + k, d.end());
    for (size_t n = 1; n < k; ++n) {
      const size_t j = d[n].second;
      const bool listed = j < i && std::any_of(pairs.begin(), pairs.end(), [&](const Pair& p) {
        return p.a == j && p.b == i;
      });
      if (!listed) pairs.push_back({std::min(i, j), std::max(i, j), d[n].first * 1e3});
    }
  }
  return pairs;
}

// A candidate's spots, imaged by spheres of any apex radius.
class SpacingProbe {
 public:
  SpacingProbe(const model::IdealImageParams& ideal, const model::TopographerParams& topographer)
      : topographer_{topographer}, design_(model::DesignNullScreen(ideal, topographer)),
        pairs_(NeighbourPairs(design_.targets)) {}
  bool Designed() const { return design_.failures.empty() && !design_.targets.empty(); }
  const std::vector<Pair>& pairs() const { return pairs_; }

  // Nearest centre spacing, the smallest gap between spot images of radius spot_radius_um (ideal image) scaled by
  // the local magnification, and the largest spot radius that leaves min_gap_px, on a sphere of that apex radius;
  // nullopt when a spot is not formed.
  std::optional<SpotSpacing> At(double apex_radius_mm, double spot_radius_um, double pitch_um,
                                double min_gap_px) const {
    const auto image = model::SynthesizeImage(model::Sphere{apex_radius_mm}, topographer_, design_.targets);
    if (!image.failures.empty() || image.spots.size() != design_.targets.size()) return std::nullopt;
    return Between(image, spot_radius_um, pitch_um, min_gap_px);
  }
  // The spots of any cornea; Between then measures them.
  model::SyntheticImage Image(const model::Surface& cornea) const {
    return model::SynthesizeImage(cornea, topographer_, design_.targets);
  }
  // At's figures for an image, over the pairs whose spots both form (a cornea's edge may lose a few); nullopt when
  // none does.
  std::optional<SpotSpacing> Between(const model::SyntheticImage& image, double spot_radius_um, double pitch_um,
                                     double min_gap_px) const {
    std::map<model::SpotId, const model::ImageSpot*> formed;
    for (const auto& spot : image.spots) formed[spot.id] = &spot;
    SpotSpacing s{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                  std::numeric_limits<double>::infinity()};
    bool any = false;
    for (const auto& p : pairs_) {
      const auto a = formed.find(design_.targets[p.a].id), b = formed.find(design_.targets[p.b].id);
      if (a == formed.end() || b == formed.end()) continue;
      const double image_um = (a->second->position_mm - b->second->position_mm).norm() * 1e3;
      const double magnification = image_um / p.ideal_um;
      s.min_spacing_um = std::min(s.min_spacing_um, image_um);
      s.min_gap_px = std::min(s.min_gap_px, (image_um - 2.0 * spot_radius_um * magnification) / pitch_um);
      s.max_spot_radius_um = std::min(s.max_spot_radius_um, 0.5 * (image_um - min_gap_px * pitch_um) / magnification);
      any = true;
    }
    if (!any) return std::nullopt;
    return s;
  }
  bool Resolves(double apex_radius_mm, double spot_radius_um, const ScreenDesignGoal& g) const {
    const auto s = At(apex_radius_mm, spot_radius_um, g.pixel_pitch_um, g.min_gap_px);
    return s && s->min_gap_px >= g.min_gap_px;
  }

 private:
  model::Topographer topographer_;
  model::NullScreenDesign design_;
  std::vector<Pair> pairs_;
};

// The apex radii within the scan on which every spot resolves: the steepest by bisection (the gap grows with the
// radius), the flattest by steps up to the scan's end. NaN, NaN when none in [steepest, flattest of the goal] does.
std::pair<double, double> ResolvingRange(const SpacingProbe& probe, double spot_radius_um, const ScreenDesignGoal& g) {
  const auto ok = [&](double r) { return probe.Resolves(r, spot_radius_um, g); };
  double hi = kNaN;
  for (double r : {g.steepest_radius_mm, 0.5 * (g.steepest_radius_mm + g.flattest_radius_mm), g.flattest_radius_mm}) {
    if (ok(r)) {
      hi = r;
      break;
    }
  }
  if (std::isnan(hi)) return {kNaN, kNaN};
  double steep = kScanSteepestMm;
  if (!ok(steep)) {
    double lo = kScanSteepestMm;
    steep = hi;
    while (steep - lo > kResolveToleranceMm) {
      const double mid = 0.5 * (lo + steep);
      (ok(mid) ? steep : lo) = mid;
    }
  }
  double flat = hi;
  while (flat + kFlatScanStepMm <= kScanFlattestMm + 1e-9 && ok(flat + kFlatScanStepMm)) flat += kFlatScanStepMm;
  if (flat < kScanFlattestMm && ok(kScanFlattestMm)) flat = kScanFlattestMm;
  return {steep, flat};
}

// Page size, narrowest printed ellipse (second moments of its outline: an ellipse's boundary, sampled evenly in its
// parameter, has variance b^2 / 2 across) and narrowest printed gap between neighbouring outlines (nearest outline
// points on the cone; the development is an isometry, so the printed gap is the same to the chord's sag).
void MeasurePrint(const model::IdealImageParams& ideal, const model::TopographerParams& topographer,
                  const std::vector<Pair>& pairs, ScreenCandidate* c) {
  const auto layout = model::LayoutNullScreen(ideal, topographer);
  const Eigen::Vector2d page = plot::NullScreenPageSizeMm(layout, {});
  c->page_width_mm = page.x();
  c->page_height_mm = page.y();
  c->min_printed_width_mm = c->min_printed_gap_mm = std::numeric_limits<double>::infinity();
  std::map<model::SpotId, size_t> outline_of;
  for (size_t k = 0; k < layout.outlines.size(); ++k) {
    const auto& pts = layout.outlines[k].sheet_mm;
    outline_of[layout.outlines[k].id] = k;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& p : pts) mean += p / pts.size();
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const auto& p : pts) cov += (p - mean) * (p - mean).transpose() / pts.size();
    const double lambda_min = 0.5 * (cov.trace() - std::hypot(cov(0, 0) - cov(1, 1), 2.0 * cov(0, 1)));
    c->min_printed_width_mm = std::min(c->min_printed_width_mm, 2.0 * std::sqrt(2.0 * std::max(0.0, lambda_min)));
  }
  const auto ids = model::IdealImage(ideal);
  for (const auto& p : pairs) {
    const auto a = outline_of.find(ids[p.a].id), b = outline_of.find(ids[p.b].id);
    if (a == outline_of.end() || b == outline_of.end()) continue;  // a key's gap: nothing printed
    double d2 = std::numeric_limits<double>::infinity();
    for (const auto& pa : layout.outlines[a->second].on_cone_mm) {
      for (const auto& pb : layout.outlines[b->second].on_cone_mm) d2 = std::min(d2, (pa - pb).squaredNorm());
    }
    c->min_printed_gap_mm = std::min(c->min_printed_gap_mm, std::sqrt(d2));
  }
}

std::string PrintRefusal(const ScreenCandidate& c, const ScreenDesignGoal& g) {
  const double lo = std::min(g.max_page_mm[0], g.max_page_mm[1]), hi = std::max(g.max_page_mm[0], g.max_page_mm[1]);
  if (std::min(c.page_width_mm, c.page_height_mm) > lo || std::max(c.page_width_mm, c.page_height_mm) > hi) {
    return fmt::format("max_page_mm: the sheet needs {:.0f} x {:.0f} mm", c.page_width_mm, c.page_height_mm);
  }
  if (c.min_printed_width_mm < g.min_printed_feature_mm || c.min_printed_gap_mm < g.min_printed_feature_mm) {
    return fmt::format("min_printed_feature_mm: printed ellipses {:.2f} mm wide, {:.2f} mm apart",
                       c.min_printed_width_mm, c.min_printed_gap_mm);
  }
  return "";
}

// The spot images of the goal corneas, which an ablation's blend zone or a cone crowds more than the steepest
// sphere does: the largest spot radius that leaves min_gap_px on every one of them and the cornea that sets it.
struct CorneaGaps {
  std::vector<model::SyntheticImage> images;
  double max_spot_radius_um = std::numeric_limits<double>::infinity();  // infinite when none images the pattern
  std::string tightest;
};
CorneaGaps GapsOnCorneas(const SpacingProbe& probe, const std::vector<model::TestCornea>& corneas,
                         const ScreenDesignGoal& g) {
  CorneaGaps out;
  for (const auto& cornea : corneas) {
    out.images.push_back(probe.Image(cornea.surface));
    const auto s = probe.Between(out.images.back(), g.max_spot_radius_um, g.pixel_pitch_um, g.min_gap_px);
    if (s && s->max_spot_radius_um < out.max_spot_radius_um) {
      out.max_spot_radius_um = s->max_spot_radius_um;
      out.tightest = cornea.name;
    }
  }
  return out;
}

// The spot-centre noise (px) a candidate with spots of radius_um is measured with: the goal's for spots of
// max_spot_radius_um, larger by max_spot_radius_um / radius for smaller ones (photon-limited).
double CentreNoisePx(const ScreenDesignGoal& g, double radius_um) {
  return radius_um > 0 ? g.spot_noise_px * std::max(1.0, g.max_spot_radius_um / radius_um) : g.spot_noise_px;
}

// The goal corneas' spots given to the pattern matcher (correct::IndexSpots) as a capture's would be — exact, and
// with the candidate's centre noise (one seeded draw per cornea) when the goal has noise — their identities compared
// with the truth: a design whose lattice the matcher misreads or cannot start on, on an eye it is designed for, is
// refused (empty: every identity given is right). Sets the smallest share identified.
std::string IdentificationRefusal(const std::vector<model::SyntheticImage>& images,
                                  const std::vector<model::TestCornea>& corneas, double noise_mm,
                                  ScreenCandidate* c) {
  c->identified_share = 1.0;
  for (size_t k = 0; k < corneas.size(); ++k) {
    const auto& spots = images[k].spots;
    for (const double sd_mm : {0.0, noise_mm}) {
      std::mt19937 rng(static_cast<unsigned>(k + 1));
      std::normal_distribution<double> noise(0.0, 1.0);
      std::vector<Eigen::Vector2d> mm;
      mm.reserve(spots.size());
      for (const auto& s : spots) {
        mm.push_back(sd_mm > 0 ? Eigen::Vector2d(s.position_mm + sd_mm * Eigen::Vector2d(noise(rng), noise(rng)))
                               : s.position_mm);
      }
      const auto indexing = correct::IndexSpots(mm, c->ideal);
      const std::string draw = sd_mm > 0 ? fmt::format(" (spots with {:.3f} um of noise)", sd_mm * 1e3) : "";
      if (!indexing.ok || indexing.spots.empty()) {
        c->identified_share = 0;
        return fmt::format("identification: the pattern matcher finds no identity on {}{}", corneas[k].name, draw);
      }
      int wrong = 0;
      for (const auto& s : indexing.spots) wrong += !(s.id == spots[s.detection].id);
      if (wrong > 0) {
        c->identified_share = kNaN;  // no share of right identities to report
        return fmt::format("identification: {} of the {} identities the pattern matcher gives on {}{} are wrong",
                           wrong, indexing.spots.size(), corneas[k].name, draw);
      }
      c->identified_share = std::min(c->identified_share, static_cast<double>(indexing.spots.size()) / spots.size());
      if (noise_mm == 0) break;
    }
  }
  return "";
}

// Everything but the map error: the spot radius, resolvability, print and identification of one candidate.
ScreenCandidate Assess(const model::IdealImageParams& ideal, bool base, const model::TopographerParams& topographer,
                       const ScreenDesignGoal& g, const std::vector<model::TestCornea>& corneas) {
  ScreenCandidate c;
  c.ideal = ideal;
  c.base = base;
  c.spots = ideal.SpotCount();
  c.tangential_rms_D.assign(g.corneas.size(), kNaN);
  c.worst_tangential_rms_D = kNaN;
  c.steepest_resolved_mm = c.flattest_resolved_mm = c.min_gap_corneas_px = c.identified_share = kNaN;
  const SpacingProbe probe(ideal, topographer);
  const auto steep = probe.At(g.steepest_radius_mm, ideal.spot_radius_um, g.pixel_pitch_um, g.min_gap_px);
  const auto flat = probe.At(g.flattest_radius_mm, ideal.spot_radius_um, g.pixel_pitch_um, g.min_gap_px);
  if (!probe.Designed() || !steep || !flat) {
    c.refused = "steepest_radius_mm, flattest_radius_mm: a spot's ray misses the cone or the cornea";
    return c;
  }
  const CorneaGaps on_corneas = GapsOnCorneas(probe, corneas, g);
  // Rounded down to 0.01 um: a value the configuration file holds exactly, and the gap it leaves is never below
  // min_gap_px by a rounding error.
  if (!base) {
    c.ideal.spot_radius_um = std::floor(100.0 * std::min({g.max_spot_radius_um, steep->max_spot_radius_um,
                                                          on_corneas.max_spot_radius_um})) / 100.0;
  }
  const double r = c.ideal.spot_radius_um;
  c.min_spacing_steep_um = steep->min_spacing_um;
  c.min_spacing_flat_um = flat->min_spacing_um;
  c.min_gap_steep_px = probe.At(g.steepest_radius_mm, r, g.pixel_pitch_um, g.min_gap_px)->min_gap_px;
  c.min_gap_flat_px = probe.At(g.flattest_radius_mm, r, g.pixel_pitch_um, g.min_gap_px)->min_gap_px;
  for (const auto& image : on_corneas.images) {
    if (const auto s = probe.Between(image, r, g.pixel_pitch_um, g.min_gap_px)) {
      c.min_gap_corneas_px =
          std::isnan(c.min_gap_corneas_px) ? s->min_gap_px : std::min(c.min_gap_corneas_px, s->min_gap_px);
    }
  }
  std::tie(c.steepest_resolved_mm, c.flattest_resolved_mm) = ResolvingRange(probe, r, g);
  const bool cornea_sets_it = on_corneas.max_spot_radius_um < steep->max_spot_radius_um;
  if (r < g.min_spot_radius_um) {
    c.refused = fmt::format("min_spot_radius_um: spots of {:.1f} um at most leave {} px {}", r, g.min_gap_px,
                            cornea_sets_it ? "on " + on_corneas.tightest
                                           : fmt::format("at {} mm", g.steepest_radius_mm));
  } else if (c.min_gap_steep_px < g.min_gap_px) {
    c.refused = fmt::format("min_gap_px: spot images {:.1f} px apart at steepest_radius_mm = {}", c.min_gap_steep_px,
                            g.steepest_radius_mm);
  } else if (c.min_gap_corneas_px < g.min_gap_px) {
    c.refused = fmt::format("min_gap_px: spot images {:.1f} px apart on a goal cornea", c.min_gap_corneas_px);
  }
  MeasurePrint(c.ideal, topographer, probe.pairs(), &c);
  if (c.refused.empty()) c.refused = PrintRefusal(c, g);
  if (c.refused.empty()) {
    c.refused = IdentificationRefusal(on_corneas.images, corneas, CentreNoisePx(g, r) * g.pixel_pitch_um * 1e-3, &c);
  }
  return c;
}

}  // namespace

std::optional<SpotSpacing> SpotSpacingAt(const model::IdealImageParams& ideal, const model::TopographerParams& topographer,
                                         double apex_radius_mm, double pixel_pitch_um, double min_gap_px) {
  const SpacingProbe probe(ideal, topographer);
  if (!probe.Designed()) return std::nullopt;
  return probe.At(apex_radius_mm, ideal.spot_radius_um, pixel_pitch_um, min_gap_px);
}

namespace {

std::string DesignName(const ScreenCandidate& c) {
  return fmt::format("{} rings x {}{}", c.ideal.rings_N + 1, c.ideal.eta,
                     c.ideal.eta0 != c.ideal.eta ? fmt::format(" (eta0 {})", c.ideal.eta0) : "");
}

// The same with the knot spacing, for the choice's reason.
std::string DesignAndKnots(const ScreenCandidate& c) {
  return fmt::format("{}, knots every {:g} mm", DesignName(c), c.spline_spacing_mm);
}

// Every candidate that resolves and prints, measured on every goal cornea (one work item per pair, written by index).
void MeasureMapErrors(const model::Config& base, const ScreenDesignGoal& g, const ScreenDesignOptions& options,
                      std::vector<ScreenCandidate>* candidates) {
  const auto corneas = model::FreeformTestSubset(g.corneas);
  std::vector<std::pair<size_t, size_t>> items;
  for (size_t c = 0; c < candidates->size(); ++c) {
    if ((*candidates)[c].refused.empty()) {
      for (size_t k = 0; k < corneas.size(); ++k) items.emplace_back(c, k);
    }
  }
  std::atomic<size_t> done{0};
  std::vector<std::string> failure(items.size());
  util::ParallelFor(items.size(), options.jobs, [&](size_t i) {
    const auto [c, k] = items[i];
    model::Config config = base;
    const ScreenCandidate& candidate = (*candidates)[c];
    config.ideal_image = candidate.ideal;
    config.reconstruction.surface_model = g.surface_model;
    config.reconstruction.spline_spacing_mm = candidate.spline_spacing_mm;
    // Seeded per cornea (the same seed for every candidate): the same result whatever the thread count.
    const double noise_mm = candidate.spot_noise_px * g.pixel_pitch_um * 1e-3;
    try {
      const auto measured =
          topo::MeasureSimulatedCornea(corneas[k].surface, config, noise_mm, static_cast<unsigned>(k + 1));
      (*candidates)[c].tangential_rms_D[k] = measured.comparison.tangential_rms_D;
      if (const auto why = topo::SplineUndetermined(measured.analysis.reconstruction)) {
        failure[i] = fmt::format("{}: {}", corneas[k].name, *why);
      }
    } catch (const std::runtime_error& e) {
      failure[i] = fmt::format("the reconstruction of {} failed: {}", corneas[k].name, e.what());
    }
    if (options.progress) options.progress(++done, items.size());
  });
  for (size_t i = 0; i < items.size(); ++i) {
    if (!failure[i].empty() && (*candidates)[items[i].first].refused.empty()) {
      (*candidates)[items[i].first].refused = failure[i];
    }
  }
  for (auto& c : *candidates) {
    if (!c.refused.empty()) continue;
    c.worst_tangential_rms_D = *std::max_element(c.tangential_rms_D.begin(), c.tangential_rms_D.end());
    c.meets_goal = !g.max_tangential_rms_D || c.worst_tangential_rms_D <= *g.max_tangential_rms_D;
  }
}

// The choice among the candidates that resolve and print (see the header); `why` says why, or names the goal key
// that cannot be met.
void Choose(const ScreenDesignGoal& g, ScreenDesignResult* r) {
  const auto& cs = r->candidates;
  std::vector<size_t> ok;
  for (size_t i = 0; i < cs.size(); ++i) {
    if (cs[i].refused.empty()) ok.push_back(i);
  }
  if (ok.empty()) {
    // The sparsest candidate's reason: the one most likely to meet the constraints, so its reason is the binding one.
    const auto sparsest = std::min_element(cs.begin(), cs.end(), [](const auto& a, const auto& b) {
      return a.spots < b.spots;
    });
    r->why = fmt::format("{} (no candidate of the grid resolves and prints; the sparsest, {}, {} spots)",
                         sparsest->refused, DesignName(*sparsest), sparsest->spots);
    return;
  }
  const auto best = *std::min_element(ok.begin(), ok.end(), [&](size_t a, size_t b) {
    return cs[a].worst_tangential_rms_D < cs[b].worst_tangential_rms_D;
  });
  const auto fewer_spots = [&](size_t a, size_t b) {
    return cs[a].spots != cs[b].spots ? cs[a].spots < cs[b].spots
                                      : cs[a].worst_tangential_rms_D < cs[b].worst_tangential_rms_D;
  };
  std::vector<size_t> eligible;
  for (size_t i : ok) {
    const bool good = g.max_tangential_rms_D
                          ? cs[i].meets_goal
                          : cs[i].worst_tangential_rms_D <= (1.0 + kNegligibleErrorGain) * cs[best].worst_tangential_rms_D;
    if (good) eligible.push_back(i);
  }
  if (eligible.empty()) {
    r->why = fmt::format("max_tangential_rms_D: no candidate that resolves and prints meets {} D; the best, {} ({} "
                         "spots), has {:.2f} D",
                         *g.max_tangential_rms_D, DesignAndKnots(cs[best]), cs[best].spots,
                         cs[best].worst_tangential_rms_D);
    return;
  }
  const size_t chosen = *std::min_element(eligible.begin(), eligible.end(), fewer_spots);
  r->chosen = chosen;
  const auto& c = cs[chosen];
  std::string resolves = fmt::format("resolves {:.2f}-{:.1f} mm, prints on {:.0f} x {:.0f} mm", c.steepest_resolved_mm,
                                     c.flattest_resolved_mm, c.page_width_mm, c.page_height_mm);
  if (!g.max_tangential_rms_D && !c.base && c.ideal.rings_N + 1 == *std::max_element(g.rings.begin(), g.rings.end())) {
    resolves += "; at the grid's most rings: more may do better (extend \"rings\")";
  }
  if (g.max_tangential_rms_D) {
    r->why = fmt::format("{} ({} spots, spot radius {:.2f} um): the fewest spots of the {} candidates that resolve and "
                         "print with the worst tangential RMS within {} D ({:.2f} D); {}",
                         DesignAndKnots(c), c.spots, c.ideal.spot_radius_um, ok.size(), *g.max_tangential_rms_D,
                         c.worst_tangential_rms_D, resolves);
  } else {
    r->why = fmt::format("{} ({} spots, spot radius {:.2f} um): worst tangential RMS {:.2f} D, {} of the {} candidates "
                         "that resolve and print (lowest {:.2f} D; fewer spots taken within {:.0f} % of it); {}",
                         DesignAndKnots(c), c.spots, c.ideal.spot_radius_um, c.worst_tangential_rms_D,
                         chosen == best ? "the lowest" : "the fewest spots near the lowest", ok.size(),
                         cs[best].worst_tangential_rms_D, 100 * kNegligibleErrorGain, resolves);
  }
}

}  // namespace

ScreenDesignResult OptimizeScreenDesign(const model::Config& base, const ScreenDesignGoal& goal,
                                        const ScreenDesignOptions& options) {
  std::string why;
  if (!goal.IsValid(&why)) throw util::InputError("ScreenDesignGoal: " + why);
  ScreenDesignResult r;
  const double base_spacing = base.reconstruction.spline_spacing_mm;
  const std::vector<double> spacings = goal.spline_spacing_mm.empty() ? std::vector<double>{base_spacing}
                                                                      : goal.spline_spacing_mm;
  const auto with_knots = [&](ScreenCandidate c, double spacing) {
    c.spline_spacing_mm = spacing;
    c.spot_noise_px = CentreNoisePx(goal, c.ideal.spot_radius_um);
    return c;
  };
  const auto corneas = model::FreeformTestSubset(goal.corneas);  // an unknown name throws before any work
  // The designs of the grid, the base first, assessed in parallel (each by index: the order does not depend on the
  // thread count).
  std::vector<model::IdealImageParams> designs = {base.ideal_image};
  for (int rings : goal.rings) {
    for (int eta : goal.eta) {
      model::IdealImageParams ideal = base.ideal_image;
      ideal.rings_N = rings - 1;
      ideal.eta0 = ideal.eta = eta;
      if (ideal.orientation_key && ideal.rings_N < 4) continue;  // the key needs three distinct rings (config.h)
      designs.push_back(ideal);
    }
  }
  std::vector<ScreenCandidate> assessed(designs.size());
  util::ParallelFor(designs.size(), options.jobs, [&](size_t i) {
    assessed[i] = Assess(designs[i], i == 0, base.topographer, goal, corneas);
  });
  const ScreenCandidate& base_design = assessed.front();
  r.candidates.push_back(with_knots(base_design, base_spacing));
  for (size_t i = 1; i < assessed.size(); ++i) {
    const ScreenCandidate& c = assessed[i];
    const auto& b = base_design.ideal;
    const bool same_design = c.ideal.rings_N == b.rings_N && c.ideal.eta0 == b.eta0 && c.ideal.eta == b.eta &&
                             c.ideal.spot_radius_um == b.spot_radius_um;
    for (double spacing : spacings) {
      if (!(same_design && spacing == base_spacing)) r.candidates.push_back(with_knots(c, spacing));
    }
  }
  MeasureMapErrors(base, goal, options, &r.candidates);
  Choose(goal, &r);
  if (r.chosen) {
    r.config = base;
    r.config.ideal_image = r.candidates[*r.chosen].ideal;
    r.config.reconstruction.surface_model = goal.surface_model;
    r.config.reconstruction.surface_model_given = true;
    r.config.reconstruction.spline_spacing_mm = r.candidates[*r.chosen].spline_spacing_mm;
  }
  return r;
}

std::string ScreenDesignTable(const ScreenDesignResult& result, const ScreenDesignGoal& g) {
  const auto num = [](double v, int digits) { return std::isnan(v) ? std::string("-") : fmt::format("{:.{}f}", v, digits); };
  const auto range = [&](const ScreenCandidate& c) {
    if (std::isnan(c.steepest_resolved_mm)) return std::string("none");
    return fmt::format("{}{:.2f}-{:.1f}{}", c.steepest_resolved_mm <= kScanSteepestMm ? "<=" : "",
                       c.steepest_resolved_mm, c.flattest_resolved_mm, c.flattest_resolved_mm >= kScanFlattestMm ? "+" : "");
  };
  std::string t = "| design | spots | spot r um | knots mm | spot noise px |";
  for (const auto& n : g.corneas) t += " " + n + " tgRMS D |";
  t += fmt::format(" worst D | spacing um at {} / {} mm | gap px at {} / {} mm | gap px on the corneas | "
                   "identified % | resolves, mm | page mm | printed width / gap mm | verdict |\n|---|---|---|---|---|",
                   g.steepest_radius_mm, g.flattest_radius_mm, g.steepest_radius_mm, g.flattest_radius_mm);
  for (size_t k = 0; k < g.corneas.size(); ++k) t += "---|";
  t += "---|---|---|---|---|---|---|---|---|\n";
  for (size_t i = 0; i < result.candidates.size(); ++i) {
    const auto& c = result.candidates[i];
    t += fmt::format("| {}{} | {} | {:.2f} | {:g} | {:.3f} |", DesignName(c), c.base ? " (base)" : "", c.spots,
                     c.ideal.spot_radius_um, c.spline_spacing_mm, c.spot_noise_px);
    for (double e : c.tangential_rms_D) t += fmt::format(" {} |", num(e, 2));
    const std::string verdict = result.chosen == i ? "**chosen**"
                                : !c.refused.empty() ? c.refused
                                : !g.max_tangential_rms_D ? "resolves, prints"
                                : c.meets_goal ? "meets the goal"
                                               : "misses max_tangential_rms_D";
    t += fmt::format(" {} | {:.1f} / {:.1f} | {:.2f} / {:.2f} | {} | {} | {} | {:.0f} x {:.0f} | {:.2f} / {:.2f} "
                     "| {} |\n",
                     num(c.worst_tangential_rms_D, 2), c.min_spacing_steep_um, c.min_spacing_flat_um,
                     c.min_gap_steep_px, c.min_gap_flat_px, num(c.min_gap_corneas_px, 2),
                     num(100.0 * c.identified_share, 1), range(c),
                     c.page_width_mm, c.page_height_mm,
                     c.min_printed_width_mm, c.min_printed_gap_mm, verdict);
  }
  t += fmt::format("\n{}{}\n", result.chosen ? "Chosen: " : "No design chosen: ", result.why);
  return t;
}

}  // namespace topocal::pipeline

#include "correct/spot_index.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <queue>
#include <set>
#include <utility>

#include <Eigen/LU>
#include <fmt/format.h>

#include "correct/spot_index_state.h"
#include "correct/spot_lattice.h"
#include "util/median.h"

namespace topocal::correct {
namespace {

using spot_index_detail::Seed;
using spot_index_detail::StartCandidates;
using spot_index_detail::State;

using lattice::DetectionGrid;
using lattice::LocalAffine;
using lattice::Template;

// Neighbours of a designed spot must spread at least this many of its spacings in both directions for its local
// affine prediction (one arc of neighbours leaves the radial scale unknown).
constexpr double kMinSpreadSpacings = 0.3;
constexpr int kMinDetections = 8;  // fewer than one ring: nothing to anchor the pattern on
constexpr size_t kStartCandidatesTried = 5;
// A lattice whose checks refused more than this many identities per identity kept is not trusted. Measured on every
// capture of the test suite (tests/correct, tests/pipeline; 290 lattices): at most 0.28 on the lattice kept; the
// lattices of dense screens whose identities were all or mostly wrong (docs/spot-identification.md): 0.51 and 0.89.
constexpr double kMaxRefusedPerKept = 0.4;
// A lattice that gives an identity to fewer than this share of the detections may have grown from a start a spot
// off (the severe decentred cone on a 16-ring x 6 screen: 375 identities, all wrong and consistent, of 816
// detections): stretched starts are tried too. A right lattice identifies >= 0.99 of a clean capture's detections
// and >= 0.90 of a lidded one's (tests/correct/spot_index_capture_test.cc); glints and skin add a few per cent.
constexpr double kMinExplainedShare = 0.75;

using util::Median;

// ---- 2. Growth ----

struct Candidate {
  double rank;
  int j, i;
};

// The candidate detection for designed spot j from its identified neighbours, if unambiguous. Its rank is the
// ambiguity: the distance to the prediction over the distance to the nearest alternative (a second detection, or
// another designed spot's prediction); lower is surer.
bool Propose(const State& st, int j, const IndexingOptions& o, Candidate* out) {
  LocalAffine map;
  if (!lattice::FitLocalAffine(st.tpl, j, st.det_of_tpl, st.det, kMinSpreadSpacings, &map)) return false;
  const Eigen::Vector2d pj = map(st.tpl.spots[j].position_mm);
  const double local_spacing = st.tpl.spacing[j] * map.MinScale();
  const double gate = o.gate_fraction * local_spacing;
  int best, second;
  double d1, d2;
  const auto free = [&](int i) { return st.tpl_of_det[i] < 0 && !st.refused.count({j, i}); };
  st.grid.Nearest2(pj, gate / o.ambiguity_ratio, free, &best, &d1, &second, &d2);
  if (best < 0 || d1 > gate) return false;
  double alternative = second >= 0 ? d2 : gate / o.ambiguity_ratio;  // two detections where one spot should be
  const Eigen::Vector2d& p = st.det[best];
  for (const int k : st.tpl.neighbours[j]) {
    if (st.det_of_tpl[k] >= 0) {
      // A detection hard by an identified spot is a glint or a split blob, not the next spot.
      if ((p - st.det[st.det_of_tpl[k]]).norm() < 0.5 * local_spacing) return false;
    } else {
      alternative = std::min(alternative, (p - map(st.tpl.spots[k].position_mm)).norm());
    }
  }
  const double rank = d1 / alternative;
  if (rank > o.ambiguity_ratio) return false;
  *out = {rank, j, best};
  return true;
}

// Best-first growth: the surest proposal is accepted first and its unidentified neighbours propose again with the
// new support, so that interpolations come before extrapolations and a spot in a compressed zone (an ablation's
// blend, a cone's flank) is predicted from its own ring's identified neighbours before it is guessed from the next
// ring. Returns the number of identities added.
int Grow(State& st, const IndexingOptions& o) {
  const int n = static_cast<int>(st.tpl.spots.size());
  struct Queued {
    Candidate c;
    int version;
    bool operator<(const Queued& b) const { return c.rank != b.c.rank ? c.rank > b.c.rank : c.j > b.c.j; }
  };
  std::priority_queue<Queued> queue;
  std::vector<int> version(n, 0);
  const auto propose = [&](int j) {
    Candidate c;
    if (Propose(st, j, o, &c)) queue.push({c, ++version[j]});
  };
  for (int j = 0; j < n; ++j) {
    if (st.det_of_tpl[j] >= 0) continue;
    bool touches = false;
    for (const int k : st.tpl.neighbours[j]) touches |= st.det_of_tpl[k] >= 0;
    if (touches) propose(j);
  }
  int added = 0;
  while (!queue.empty()) {
    const Queued q = queue.top();
    queue.pop();
    if (q.version != version[q.c.j] || st.det_of_tpl[q.c.j] >= 0) continue;
    if (st.tpl_of_det[q.c.i] >= 0) {  // its detection was taken meanwhile
      propose(q.c.j);
      continue;
    }
    st.Assign(q.c.j, q.c.i);
    ++added;
    for (const int k : st.tpl.neighbours[q.c.j]) {
      if (st.det_of_tpl[k] < 0) propose(k);
    }
  }
  return added;
}

// ---- 3. Check ----

// Leave-one-out residual of identity j in units of its local spacing; infinity when its neighbours cannot predict it.
double LooResidual(const State& st, int j, double* residual_abs) {
  LocalAffine map;
  if (!lattice::FitLocalAffine(st.tpl, j, st.det_of_tpl, st.det, kMinSpreadSpacings, &map)) {
    *residual_abs = 0;
    return std::numeric_limits<double>::infinity();
  }
  *residual_abs = (st.det[st.det_of_tpl[j]] - map(st.tpl.spots[j].position_mm)).norm();
  return *residual_abs / (st.tpl.spacing[j] * map.MinScale());
}

// Quadrants about designed position q that hold an identified designed spot within 1.6 spacings of q (among
// designed spot j and its neighbours, `exclude` left out): 4 inside the identified lattice, 2 or fewer at its edge.
int IdentifiedSides(const State& st, int j, const Eigen::Vector2d& q, int exclude) {
  unsigned sides = 0;
  const auto add = [&](int k) {
    const Eigen::Vector2d dq = st.tpl.spots[k].position_mm - q;
    if (k != exclude && st.det_of_tpl[k] >= 0 && dq.norm() < 1.6 * st.tpl.spacing[k]) {
      sides |= 1u << ((dq.x() > 0) + 2 * (dq.y() > 0));
    }
  };
  add(j);
  for (const int k : st.tpl.neighbours[j]) add(k);
  return __builtin_popcount(sides);
}

// Drops the identities inconsistent with their neighbours, worst first. An identity at the lattice's edge (support
// from one side: a lid's margin, the pattern's rim) is held to a tighter floor, 0.6 of the interior's: there a
// stray blob (a glint on the lid margin) can sit near where a hidden spot would be, and nothing on the far side
// contradicts it. Returns the number dropped. An identity's residual and edge depend on its neighbours' identities
// alone, so after each drop only the identities that count the dropped one as a neighbour are measured again (the
// same residuals as measuring every identity each time; a lattice its checks refuse by the thousand took seconds).
int Check(State& st, const IndexingOptions& o) {
  const int n = static_cast<int>(st.tpl.spots.size());
  std::vector<std::vector<int>> counted_by(n);  // the designed spots that have j among their neighbours
  for (int k = 0; k < n; ++k) {
    for (const int j : st.tpl.neighbours[k]) counted_by[j].push_back(k);
  }
  std::vector<double> r(n, -1);
  std::vector<bool> edge(n, false);
  const auto measure = [&](int j) {
    double abs;
    r[j] = st.det_of_tpl[j] < 0 ? -1 : LooResidual(st, j, &abs);
    edge[j] = st.det_of_tpl[j] >= 0 && IdentifiedSides(st, j, st.tpl.spots[j].position_mm, j) < 3;
  };
  for (int j = 0; j < n; ++j) measure(j);
  int dropped = 0;
  std::vector<double> finite;
  for (;;) {
    finite.clear();
    for (int j = 0; j < n; ++j) {
      if (r[j] >= 0 && std::isfinite(r[j])) finite.push_back(r[j]);
    }
    const double spread = o.residual_gate_sigmas * 1.4826 * Median(finite);
    const double inner = std::min(o.gate_fraction, std::max(spread, o.residual_gate_floor_fraction));
    const double outer = std::min(o.gate_fraction, std::max(spread, 0.6 * o.residual_gate_floor_fraction));
    int worst = -1;
    double worst_ratio = 1;
    for (int j = 0; j < n; ++j) {
      const double ratio = r[j] / (edge[j] ? outer : inner);
      if (r[j] >= 0 && ratio > worst_ratio) {
        worst_ratio = ratio;
        worst = j;
      }
    }
    if (worst < 0) return dropped;
    st.refused.insert({worst, st.det_of_tpl[worst]});
    st.Unassign(worst);
    ++dropped;
    measure(worst);
    for (const int k : counted_by[worst]) measure(k);
  }
}

// A ring slip (growth stepping over a compressed ring: an ablation's blend, a cone's flank) leaves that ring's
// detections without identity INSIDE the identified lattice, between designed positions; an isolated glint leaves
// one. Each free detection within the lattice is carried back into design coordinates by the local map of its
// nearest identity; one that falls between designed spots (>= 0.35 spacings from each) with identities around it
// (in three quadrants) is unexplained. Identities
// with two or more unexplained detections in their neighbourhood are refused, and those pairings not tried again.
// Returns the number refused.
int RefuseAroundUnexplained(State& st) {
  const int n = static_cast<int>(st.tpl.spots.size());
  std::vector<int> identified;
  std::vector<Eigen::Vector2d> positions;
  for (int j = 0; j < n; ++j) {
    if (st.det_of_tpl[j] >= 0) {
      identified.push_back(j);
      positions.push_back(st.det[st.det_of_tpl[j]]);
    }
  }
  if (identified.empty()) return 0;
  const DetectionGrid labelled(positions, st.tpl.ring_step);
  std::vector<int> unexplained_near(n, 0);
  for (size_t i = 0; i < st.det.size(); ++i) {
    if (st.tpl_of_det[i] >= 0) continue;
    double d;
    const int nearest = labelled.Nearest(st.det[i], 4 * st.tpl.ring_step, &d);
    if (nearest < 0) continue;
    const int j = identified[nearest];
    LocalAffine map;
    if (!lattice::FitLocalAffine(st.tpl, j, st.det_of_tpl, st.det, kMinSpreadSpacings, &map)) continue;
    if (d > 1.5 * st.tpl.spacing[j] * map.MinScale()) continue;  // outside the lattice: a blob beyond its edge
    const Eigen::Vector2d q = map.q0 + map.linear.inverse() * (st.det[i] - map.offset);
    double closest = (q - st.tpl.spots[j].position_mm).norm() / st.tpl.spacing[j];
    for (const int k : st.tpl.neighbours[j]) {
      closest = std::min(closest, (q - st.tpl.spots[k].position_mm).norm() / st.tpl.spacing[k]);
    }
    // Where a designed spot is (a spot not yet identified), or at the lattice's edge (the map extrapolated).
    if (closest < 0.35 || IdentifiedSides(st, j, q, -1) < 3) continue;
    ++unexplained_near[j];
    for (const int k : st.tpl.neighbours[j]) ++unexplained_near[k];
  }
  int refused = 0;
  for (const int j : identified) {
    if (unexplained_near[j] < 2) continue;
    st.refused.insert({j, st.det_of_tpl[j]});
    st.Unassign(j);
    ++refused;
  }
  return refused;
}

// Keeps the largest set of identities connected through neighbours (the one grown from the start, unless the
// checks refused its seeds) and drops the islands: nothing ties their identities to the pattern's centre. Returns
// the number dropped.
int KeepLargestConnected(State& st) {
  const int n = static_cast<int>(st.tpl.spots.size());
  std::vector<int> component(n, -1), sizes;
  for (int seed = 0; seed < n; ++seed) {
    if (st.det_of_tpl[seed] < 0 || component[seed] >= 0) continue;
    const int id = static_cast<int>(sizes.size());
    sizes.push_back(0);
    std::vector<int> stack{seed};
    component[seed] = id;
    while (!stack.empty()) {
      const int j = stack.back();
      stack.pop_back();
      ++sizes[id];
      for (const int k : st.tpl.neighbours[j]) {
        if (component[k] < 0 && st.det_of_tpl[k] >= 0) {
          component[k] = id;
          stack.push_back(k);
        }
      }
    }
  }
  if (sizes.empty()) return 0;
  const int keep = static_cast<int>(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
  int dropped = 0;
  for (int j = 0; j < n; ++j) {
    if (st.det_of_tpl[j] >= 0 && component[j] != keep) {
      st.Unassign(j);
      ++dropped;
    }
  }
  return dropped;
}

// Growth and checks from the seeded start, alternating (final_passes), then the islands dropped. Returns the number
// of identities refused.
int Identify(State& st, const IndexingOptions& options) {
  int dropped = 0;
  for (int pass = 0; pass < options.final_passes; ++pass) {
    const int grown = Grow(st, options);
    const int refused = Check(st, options) + RefuseAroundUnexplained(st);
    dropped += refused;
    if (refused == 0 && pass > 0 && grown == 0) break;
  }
  return dropped + KeepLargestConnected(st);
}

void Report(const State& st, int dropped, SpotIndexing* out) {
  const int n_tpl = static_cast<int>(st.tpl.spots.size());
  double sum2 = 0;
  for (int j = 0; j < n_tpl; ++j) {
    if (st.det_of_tpl[j] < 0) {
      out->missing.push_back(st.tpl.spots[j].id);
      continue;
    }
    IndexedSpot s;
    s.id = st.tpl.spots[j].id;
    s.detection = st.det_of_tpl[j];
    s.position = st.det[s.detection];
    LooResidual(st, j, &s.residual);
    sum2 += s.residual * s.residual;
    out->spots.push_back(s);
  }
  std::sort(out->spots.begin(), out->spots.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  for (size_t i = 0; i < st.det.size(); ++i) {
    if (st.tpl_of_det[i] < 0) out->unassigned_detections.push_back(static_cast<int>(i));
  }
  out->residual_rms = out->spots.empty() ? 0 : std::sqrt(sum2 / out->spots.size());
  out->dropped = dropped;
  out->ok = !out->spots.empty();
  out->message = fmt::format("{} of {} designed spots indexed, {} missing, {} detections unassigned, {} identities "
                             "refused as ambiguous or inconsistent",
                             out->spots.size(), n_tpl, out->missing.size(), out->unassigned_detections.size(),
                             dropped);
}

// Whether a grown lattice still holds a quarter of rings 1-3 (its seed held half: Seed). The checks can refuse a
// seed and leave a lattice that slid outwards along the rings, consistent with itself and wrong everywhere: on the
// 26-ring x 6 screen, the 33 um cone through an assembled device under lids of 30 % and 15 %, 1,083 identities each
// two rings out, none of rings 1-3 held, 0.35 refused per kept. Nothing ties such a lattice to the pattern's centre.
// Right lattices of that screen under lids up to 40 % held 15-36 of the 36 (tests/correct/spot_index_capture_test.cc).
bool HoldsItsCentre(const State& st) {
  const std::vector<int> inner = lattice::InnerSpots(st.tpl, 3);
  const auto held = std::count_if(inner.begin(), inner.end(), [&](int j) { return st.det_of_tpl[j] >= 0; });
  return 4 * held >= static_cast<long>(inner.size());
}

// The lattices grown from the starts tried: the one kept, and the first not trusted.
struct Lattices {
  std::optional<State> best;
  int best_net = std::numeric_limits<int>::min(), best_dropped = 0;
  std::optional<std::string> untrusted;  // why the first lattice not trusted was not
};

// Seeds, grows and checks a lattice from each start candidate in turn (up to kStartCandidatesTried) until one is
// clean; `why` gets the first seed's failure.
void TryStarts(const Template& tpl, const std::vector<Eigen::Vector2d>& det, const std::vector<LocalAffine>& candidates,
               const IndexingOptions& options, Lattices* found, std::string* why) {
  for (size_t c = 0; c < std::min<size_t>(candidates.size(), kStartCandidatesTried); ++c) {
    State st(tpl, det, tpl.ring_step);
    std::string reason;
    if (!Seed(st, candidates[c], options, &reason)) {
      if (c == 0) *why = reason;
      continue;
    }
    const int dropped = Identify(st, options);
    if (dropped > kMaxRefusedPerKept * st.Assigned()) {
      if (!found->untrusted) {
        found->untrusted = fmt::format("{} refused against {} kept (a start the checks could not confirm, or a "
                                       "lattice that slipped where the pattern bends)", dropped, st.Assigned());
      }
      continue;
    }
    if (!HoldsItsCentre(st)) {
      if (!found->untrusted) {
        found->untrusted = fmt::format("of {} identities kept, too few are of rings 1-3 (a lattice that slid along "
                                       "the rings)", st.Assigned());
      }
      continue;
    }
    const int net = st.Assigned() - dropped;
    if (net > found->best_net) {
      found->best_net = net;
      found->best_dropped = dropped;
      found->best.emplace(std::move(st));
    }
    if (dropped <= std::max(3, found->best->Assigned() * 3 / 100)) return;
  }
}

}  // namespace

bool IndexingOptions::IsValid(std::string* why) const {
  const auto fail = [why](std::string m) {
    if (why) *why = std::move(m);
    return false;
  };
  if (!(gate_fraction > 0 && gate_fraction < 0.5)) return fail("gate_fraction must be in (0, 0.5)");
  if (!(ambiguity_ratio > 0 && ambiguity_ratio < 1)) return fail("ambiguity_ratio must be in (0, 1)");
  if (!(residual_gate_sigmas > 0)) return fail("residual_gate_sigmas must be > 0");
  if (!(residual_gate_floor_fraction > 0 && residual_gate_floor_fraction <= gate_fraction)) {
    return fail("residual_gate_floor_fraction must be in (0, gate_fraction]");
  }
  if (final_passes < 1) return fail("final_passes must be >= 1");
  if (!(centre_search_fraction > 0 && centre_search_fraction <= 1)) {
    return fail("centre_search_fraction must be in (0, 1]");
  }
  if (!(min_scale > 0 && max_scale >= min_scale && max_scale < 10)) return fail("need 0 < min_scale <= max_scale < 10");
  return true;
}

SpotIndexing IndexSpots(const std::vector<Eigen::Vector2d>& det, const model::IdealImageParams& ideal,
                        const IndexingOptions& options) {
  SpotIndexing out;
  std::string why;
  const int n_det = static_cast<int>(det.size());
  const auto fail = [&](std::string message) {
    out.message = std::move(message);
    out.unassigned_detections.resize(n_det);
    std::iota(out.unassigned_detections.begin(), out.unassigned_detections.end(), 0);
    for (const auto& s : model::IdealImage(ideal)) out.missing.push_back(s.id);
    return out;
  };
  if (!options.IsValid(&why)) return fail("invalid options: " + why);
  if (n_det < kMinDetections) {
    return fail(fmt::format("{} detections: too few to index (need >= {})", n_det, kMinDetections));
  }
  for (const auto& p : det) {
    if (!p.allFinite()) return fail("a detection's position is not finite");
  }
  // The pattern's template (its spots' neighbours) only once there is something to index: a frame without a spot
  // does not pay for it.
  const Template tpl = lattice::MakeTemplate(ideal);
  // Start candidates are tried best first (up to five); the next only when the identities of the last are not clean
  // (more than 3 % refused: a start off by a ring or a spot grows a lattice its own checks keep refusing). Of the
  // lattices whose checks refused at most kMaxRefusedPerKept as many identities as they kept, the one with the most
  // identities net of refusals is kept; a lattice refused more than that grew from a start the checks could not
  // confirm, or slipped where the pattern bends (an ablation's blend zone), and none of its identities is trusted.
  // When lattices grew and none is trusted, or the one kept leaves more than a quarter of the detections without an
  // identity, stretched starts are searched too (a severe cone beside the apex stretches the inner rings;
  // docs/spot-identification.md) and the lattice with the most identities net of refusals is kept.
  Lattices found;
  for (const bool sheared : {false, true}) {
    const auto candidates = StartCandidates(State(tpl, det, tpl.ring_step), options, ideal.rhoN_mm, sheared, &why);
    if (candidates.empty() && !sheared) return fail(why);
    TryStarts(tpl, det, candidates, options, &found, &why);
    if (found.best ? found.best->Assigned() >= kMinExplainedShare * n_det : !found.untrusted) break;
  }
  const auto& best = found.best;
  if (!best && found.untrusted) {
    return fail(fmt::format("the identities do not hold together: {}; is the pattern's centre covered or deformed "
                            "beyond recognition?", *found.untrusted));
  }
  if (!best) return fail(why);
  Report(*best, found.best_dropped, &out);
  return out;
}

}  // namespace topocal::correct

#pragma once
// The pattern matcher's working state and its start (correct/spot_index_start.cc; correct/spot_index.cc holds the
// growth and the checks). Internal to correct::IndexSpots: call that, not these.
#include <algorithm>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "correct/spot_index.h"
#include "correct/spot_lattice.h"

namespace topocal::correct::spot_index_detail {

// The assignment between designed spots (j) and detections (i), and the pairings the checks refused.
struct State {
  const lattice::Template& tpl;
  const std::vector<Eigen::Vector2d>& det;
  lattice::DetectionGrid grid;
  std::vector<int> det_of_tpl, tpl_of_det;
  std::set<std::pair<int, int>> refused;  // (j, i)

  State(const lattice::Template& t, const std::vector<Eigen::Vector2d>& d, double cell)
      : tpl(t), det(d), grid(d, cell), det_of_tpl(t.spots.size(), -1), tpl_of_det(d.size(), -1) {}
  void Assign(int j, int i) {
    det_of_tpl[j] = i;
    tpl_of_det[i] = j;
  }
  void Unassign(int j) {
    tpl_of_det[det_of_tpl[j]] = -1;
    det_of_tpl[j] = -1;
  }
  int Assigned() const {
    return static_cast<int>(std::count_if(det_of_tpl.begin(), det_of_tpl.end(), [](int i) { return i >= 0; }));
  }
};


// The start's candidates: the coarse hypotheses refined to affine maps of rings 1-3, best (lowest score) first.
// Empty, with the reason, when the detections give no hypothesis. `sheared` searches rotated and stretched
// hypotheses too (27 times the work), for when no isotropic start holds.
std::vector<lattice::LocalAffine> StartCandidates(const State& st, const IndexingOptions& o, double rho_n,
                                                  bool sheared, std::string* why);

// Rings 1-3 identified from a start candidate by mutual nearest neighbours, the affine map refitted once. False,
// with the reason, when fewer than half of them are found.
bool Seed(State& st, lattice::LocalAffine map, const IndexingOptions& o, std::string* why);

}  // namespace topocal::correct::spot_index_detail

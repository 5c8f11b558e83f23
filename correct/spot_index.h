#pragma once
// Spot indexing: give each detected spot its (ring, index) identity in the designed pattern (model::IdealImage), or
// none. A wrong identity is the worst failure of the instrument (its numbers look clinical and are not), so every
// identity rests on the pattern's local structure, is accepted only when unambiguous and is checked again against
// its neighbours; what cannot be checked is left without identity and counted.
//
// The spot image of any cornea is a smooth, one-to-one deformation of the ideal image, but only locally close to an
// affine one: a lid hides a whole sector, a keratoconus cone or an ablation's blend zone bends the lattice far from
// any low-order global map. Nothing here uses the spread or centroid of all detections.
//
//  1. Start: the pattern's centre and scale from its centre alone. The image's spot spacing (median distance between
//     neighbouring detections) gives the scale to within the spread of spacings; the innermost rings (a hole ringed
//     by eta0 spots, then eta0 + eta, ...) are matched over a grid of centres around the detections' median and of
//     isotropic scales about that one, scored on a distance field of the detections with truncated distances; the
//     best dozen are refined to affine maps of rings 1-3 and ranked. Rings 1-3 are then assigned from the best by
//     mutual nearest neighbours; the next candidate (up to five) is tried when its identities are not clean.
//  2. Growth, best first: every designed spot next to identified ones is predicted by the local affine map of its
//     identified neighbours (weighted by inverse squared distance, neighbours needed in both directions) and
//     proposes the nearest free detection within gate_fraction x the predicted local spacing, ranked by its
//     ambiguity (distance over the distance to the nearest alternative: a second detection, another designed
//     spot's prediction); above ambiguity_ratio it is not proposed. The surest proposal is accepted first and its
//     neighbours propose again with the new support.
//  3. Check: each identity is predicted from its identified neighbours without it (leave-one-out local affine); one
//     whose residual exceeds max(residual_gate_sigmas x the robust residual scale, residual_gate_floor_fraction x
//     the local spacing; 0.6 x that floor at the lattice's edge) is dropped, worst first, and that pairing is not
//     tried again. Growth and check alternate
//     (final_passes). A ring slip (growth stepping over a compressed ring) is found by the detections it leaves
//     without identity inside the identified lattice: identities with two such detections around them are refused.
//     Last, identities outside the largest neighbour-connected set are dropped: nothing ties them to the centre.
//  Everything unassigned is reported: detections (spurious blobs or unidentifiable) and designed spots (missing);
//  `dropped` counts the identities the checks refused.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "model/config.h"
#include "model/null_screen.h"

namespace topocal::correct {

struct IndexingOptions {
  double gate_fraction = 0.4;   // growth gate, fraction of the predicted local spot spacing
  // A detection is taken for a designed spot only when it is at most this fraction of the distance to any other
  // candidate (a second detection, or another designed spot's prediction).
  double ambiguity_ratio = 0.5;
  double residual_gate_sigmas = 6.0;  // check: leave-one-out residual limit in robust residual scales
  // Floor of the check's limit as a fraction of the local spacing: the residual may be ~0 on noise-free data, and
  // a local affine map leaves the lattice's curvature (cones, blend zones) in it.
  double residual_gate_floor_fraction = 0.25;
  int final_passes = 4;  // growth + check rounds
  // The start's search: centres within this fraction of the design radius rhoN around the detections' median (a
  // lid covering 40 % of the pattern moves the median by ~0.3 rhoN); isotropic scales from 0.75 to 1.33 x the one
  // the image's spot spacing implies, clamped to [min_scale, max_scale].
  double centre_search_fraction = 0.6;
  double min_scale = 0.7, max_scale = 1.45;
  bool IsValid(std::string* why) const;
};

struct IndexedSpot {
  model::SpotId id;
  int detection = -1;                  // index into the input
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // as given (input units)
  double residual = 0;                 // |p - prediction from its neighbours| (leave-one-out), input units
};

struct SpotIndexing {
  std::vector<IndexedSpot> spots;          // sorted by id
  std::vector<int> unassigned_detections;  // indices into the input
  std::vector<model::SpotId> missing;      // designed spots without a detection
  double residual_rms = 0;                 // of the identities' leave-one-out residuals, input units
  int dropped = 0;                          // identities refused by the checks (ambiguous or inconsistent)
  bool ok = false;                          // false: could not even start (message says why)
  std::string message;
};

// `detections_mm`: spot centres on the detection plane (mm, paper frame — any camera orientation already removed).
// Never throws for bad data: an empty or hopeless set gives ok == false with a message.
SpotIndexing IndexSpots(const std::vector<Eigen::Vector2d>& detections_mm, const model::IdealImageParams& ideal,
                        const IndexingOptions& options = {});

}  // namespace topocal::correct

#pragma once
// Spot indexing: give each detected spot its (ring, index) identity in the designed pattern (model::IdealImage).
//
// The spot image of any cornea is a smooth, one-to-one deformation of the ideal image: an anisotropic scale for an
// astigmatic cornea (any axis alpha), a radial non-linearity from asphericity and from lens distortion. The indexer
// therefore fits a deformation  p = T(q)  from ideal positions q to detected positions p and grows it outwards:
//
//  1. Start: the pattern's centre and shape from the moments of the detections (trimmed twice to shed far blobs):
//     T0(q) = mu + Sigma_p^(1/2) Sigma_q^(-1/2) q. The symmetric square root recovers a symmetric affine map (the
//     astigmatic scale along any axis) without a rotation ambiguity.
//  2. Growth, ring 1 to N+1: predict the ring's spots with the current T, take for each the nearest unassigned
//     detection within a gate of gate_fraction x the predicted local spacing, keep it only if no spot of the
//     neighbouring rings is predicted closer to it, then refit T to all assigned spots: affine while at most two
//     rings are known, a full bivariate polynomial of degree 3 (10 terms per coordinate) after that, degree 5 once
//     six rings are known. Extrapolating one ring at a time keeps the prediction error a small fraction of the
//     spacing even at the paper's strongest distortion (11 % at the pattern's edge).
//  3. Final passes: predict every spot with the final T and assign detections and spots that are each other's
//     nearest, within min(gate, residual_gate_sigmas x robust residual scale): a glint can only take a missing
//     spot's identity if it sits where that spot should be, to a few times the fit's residual.
//  Everything unassigned is reported: detections (spurious blobs or unidentifiable) and designed spots (missing).
#include <string>
#include <vector>

#include <Eigen/Core>

#include "model/config.h"
#include "model/null_screen.h"

namespace topocal::correct {

struct IndexingOptions {
  double gate_fraction = 0.4;        // growth gate, fraction of the predicted local spot spacing
  double residual_gate_sigmas = 6.0; // final gate in robust residual scales
  // Floor of the final gate as a fraction of the local spacing: the fit's residual may be ~0 on noise-free data.
  double residual_gate_floor_fraction = 0.05;
  int final_passes = 3;
  bool IsValid(std::string* why) const;
};

struct IndexedSpot {
  model::SpotId id;
  int detection = -1;                  // index into the input
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // as given (input units)
  double residual = 0;                 // |p - T(q)| of the final fit, input units
};

struct SpotIndexing {
  std::vector<IndexedSpot> spots;          // sorted by id
  std::vector<int> unassigned_detections;  // indices into the input
  std::vector<model::SpotId> missing;      // designed spots without a detection
  double residual_rms = 0;                 // of the final deformation fit, input units
  int polynomial_degree = 0;
  bool ok = false;                          // false: could not even start (message says why)
  std::string message;
};

// `detections_mm`: spot centres on the detection plane (mm, paper frame — any camera orientation already removed).
// Never throws for bad data: an empty or hopeless set gives ok == false with a message.
SpotIndexing IndexSpots(const std::vector<Eigen::Vector2d>& detections_mm, const model::IdealImageParams& ideal,
                        const IndexingOptions& options = {});

}  // namespace topocal::correct

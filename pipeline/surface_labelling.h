#pragma once
// The predict-and-label loop: identities the reconstructed surface gives to detections the pattern's own lattice
// could not tell apart (docs/spot-identification.md, "Through the surface").
//
// The lattice growth (correct/spot_index.h) refuses what is ambiguous locally: where a refractive blend zone
// compresses two or three rings to half their spacing, up to half the spots of a capture stay without identity. The
// surface the identified spots give predicts, through the device, where every missing designed spot images:
// each target's reflection point on the recovered surface (paper Eq. 15, Newton), imaged through the pinhole
// (Eq. 14a + 16) and distorted as the device distorts. A free detection is given the identity only when the
// prediction is unambiguous, and a round of new identities is kept only when the surface still represents every
// identified spot afterwards (topo::ModelFitsData); otherwise the round is withdrawn and the loop stops.
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "model/config.h"
#include "model/device.h"
#include "model/null_screen.h"
#include "pipeline/measure_spots.h"
#include "topo/analysis.h"
#include "topo/reconstruction.h"

namespace topocal::pipeline {

// Where the recovered surface images one designed spot through the device: distorted detection-plane mm, as the
// camera records.
struct PredictedSpot {
  model::SpotId id;
  Eigen::Vector2d position_mm = Eigen::Vector2d::Zero();  // distorted
};

// The spots `ids` as `surface` images them through `device` (the targets where its screen puts them, the as-built
// a). Spots whose reflection point cannot be found (the Newton solve fails or leaves the surface) are left out.
std::vector<PredictedSpot> PredictSpots(const topo::Reconstruction& surface, const std::vector<model::SpotId>& ids,
                                        const model::Device& device, const model::Config& config);

// An identified spot as the labelling sees it: where it was detected, and how far from there the surface images it
// (infinite where the surface does not image it): where the surface does not reproduce its own data, its
// predictions are not trusted.
struct IdentifiedAnchor {
  Eigen::Vector2d position_mm = Eigen::Vector2d::Zero();  // distorted
  double prediction_error_mm = 0;
};

// One labelling round's rule. A prediction p of a missing spot, with s the distance from p to the nearest other
// prediction or identified spot (the local spacing), takes the free detection d nearest to it when
//  * an identified spot lies within kReachSpacings s of p (the loop extends the identities from where they are, a
//    ring at a time, never far beyond the data that shaped the surface), and the surface images the nearest one
//    within kTrustSpacings s of where it was detected;
//  * |d - p| <= kGateSpacings s;
//  * every other free detection is at least |d - p| / kAmbiguityRatio from p, and every other prediction or
//    identified spot at least that far from d (unambiguous both ways).
inline constexpr double kGateSpacings = 0.25, kAmbiguityRatio = 0.5, kReachSpacings = 2.0, kTrustSpacings = 0.25;
inline constexpr int kMaxLabellingRounds = 12;

struct SurfaceLabel {
  model::SpotId id;
  int free_index = -1;  // into the free detections given
};
std::vector<SurfaceLabel> LabelFromPredictions(const std::vector<PredictedSpot>& predictions,
                                               const std::vector<IdentifiedAnchor>& identified,
                                               const std::vector<Eigen::Vector2d>& free_mm);

// LabelFromPredictions repeated with the spots it labels taken as identified (their distance from the prediction
// known), up to kGrowthPasses times: the identities grow along one surface before it is reconstructed again.
inline constexpr int kGrowthPasses = 20;
std::vector<SurfaceLabel> GrowFromPredictions(std::vector<PredictedSpot> predictions,
                                              std::vector<IdentifiedAnchor> identified,
                                              const std::vector<Eigen::Vector2d>& free_mm);

// Where a whole ring images off its prediction (a refractive blend zone steepens or flattens the cornea between two
// rings: the surface, continued from the rings inside, cannot know it), the ring's predictions are moved together
// along the radius from the pattern's centre by the shift that puts the most of them within the gate of a free
// detection, in steps of kRingShiftStep spacings up to kMaxRingShift either way (below a whole spacing: a shift
// onto the next ring is never tried). The shift is taken when it matches at least kRingShiftShare of the ring's
// usable predictions and kRingShiftRivalRatio times as many as any shift kRingShiftApart spacings or more away; the
// moved predictions are then labelled by GrowFromPredictions. The innermost ring so matched is labelled
// (one ring per round: the next is predicted from the surface this one reshapes).
inline constexpr double kRingShiftStep = 0.05, kMaxRingShift = 0.75, kRingShiftApart = 0.5, kRingShiftShare = 0.5,
                        kRingShiftRivalRatio = 2.0;
inline constexpr int kMinRingPredictions = 8;
std::vector<SurfaceLabel> LabelShiftedRing(const std::vector<PredictedSpot>& predictions,
                                           const std::vector<IdentifiedAnchor>& identified,
                                           const std::vector<Eigen::Vector2d>& free_mm, const Eigen::Vector2d& centre_mm);

// The loop on a measurement of an image through `device`: its identified spots analysed (RejectSurfaceOutliers,
// which counts in m->capture), then rounds of PredictSpots + LabelFromPredictions, each new identity moved from
// m->free_mm to m->detected and m->spots (undistorted through the device) and counted in
// m->capture.surface_labelled, until a round adds none, withdraws its labels, or kMaxLabellingRounds. Returns the
// analysis of the final identities. Throws what `analyze` throws.
topo::Analysis LabelThroughSurface(SpotMeasurement* m, const model::Device& device, const model::Config& config,
                                   const std::function<topo::Analysis(const std::vector<model::PlaneSpot>&)>& analyze);

}  // namespace topocal::pipeline

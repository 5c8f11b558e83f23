#pragma once
// What a capture shows and whether it can support a measurement: the capture-quality line printed with every
// measurement from an image, and the verdict that refuses one the data cannot support (wrong is worse than absent:
// a refused measurement prints its reasons and no clinical number).
#include <functional>
#include <string>
#include <vector>

#include "correct/detect_and_index.h"
#include "model/null_screen.h"
#include "model/topographer_camera.h"
#include "topo/analysis.h"

namespace topocal::pipeline {

struct CaptureQuality {
  int designed = 0;     // spots the screen shows (the orientation key's gaps excluded)
  int identified = 0;   // detections given an identity (usable + flagged)
  int usable = 0;       // identified and not flagged near a blob or at the border
  int refused = 0;      // identities the indexer's checks refused (ambiguous or inconsistent with neighbours)
  int unassigned = 0;   // blobs without identity: glints, lashes' edges, skin, refused identities
  double visible_fraction = 0;  // identified / designed
  // The largest azimuth span of the outer half of the rings without one identified spot (a lid, a lash shadow, the
  // image's edge), and on which side of the image it lies ("top", "bottom", "left", "right"; empty below 30 deg).
  double largest_gap_deg = 0;
  std::string gap_side;
  double median_spot_area_px = 0;  // of the identified spots: grows with defocus and motion blur
  // Usable spots the reconstructed surface rejected (RejectSurfaceOutliers): their slope residual stands out of
  // the others' — a centre pulled by a lash's shadow or the lid margin, or a wrong identity. By id.
  std::vector<model::SpotId> surface_outliers;
  // Free detections the reconstructed surface's prediction identified (pipeline/surface_labelling.h), counted in
  // identified and usable too.
  int surface_labelled = 0;
  std::string Line() const;        // "capture: ..." one line
};

CaptureQuality AssessCapture(const correct::DetectAndIndexResult& located, const model::TopographerCamera& camera,
                             const model::IdealImageParams& ideal);

// Below this share of the designed spots identified, no measurement is made.
inline constexpr double kMinVisibleFraction = 0.30;

struct MeasurementVerdict {
  bool valid = true;
  std::vector<std::string> reasons;  // why not, one line each
};

// The reconstructed surface's check of every usable spot (capture issue, items 1-2: each identity and centre
// against the surface the others give): `analyze` is run on `spots`; a spot whose slope residual (measured slope
// minus the surface's, at its incidence point) departs from the median residual of its 6 nearest spots by more than
// kSurfaceOutlierSigmas times the departures' robust scale (their median over that of a 2-D Gaussian's magnitude, at
// least the expected slope noise) is left out and `analyze` run again, up to kSurfaceOutlierPasses times. A shape
// the model smooths over leaves residuals neighbours share, and no spot of it is left out. More than kMaxSurfaceOutlierShare of the spots standing out means the
// model, not the spots, misses (JudgeMeasurement refuses that); none is then left out. `capture`, if given, counts
// the spots left out. Throws what `analyze` throws.
inline constexpr double kSurfaceOutlierSigmas = 6.0, kMaxSurfaceOutlierShare = 0.10;
inline constexpr int kSurfaceOutlierPasses = 3;
topo::Analysis RejectSurfaceOutliers(
    std::vector<model::PlaneSpot> spots,
    const std::function<topo::Analysis(const std::vector<model::PlaneSpot>&)>& analyze, CaptureQuality* capture);

// A measurement from an image is refused when too few spots are identified, the clinical indices cannot be computed
// from the data (the sim-K zone not covered in every direction) or the surface model does not represent the
// identified spots (topo::ModelFitsData: a wrong identity or a shape no model here can hold).
MeasurementVerdict JudgeMeasurement(const CaptureQuality& capture, const topo::Analysis& analysis);

}  // namespace topocal::pipeline

#pragma once
// A raw spot image to reconstruction input: detect and index the spots (correct/), convert to detection-plane mm
// through the camera, and undistort them with a calibrated distortion when one is given.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "correct/detect_and_index.h"
#include "pipeline/capture_quality.h"
#include "model/config.h"
#include "model/device.h"
#include "topo/device_analysis.h"
#include "model/distortion.h"
#include "model/topographer_camera.h"
#include "topo/analysis.h"
#include "topo/reconstruction.h"
#include "util/io.h"

namespace topocal::pipeline {

// The spots of one image: detected and identified (model::PlaneSpot, distorted as the camera saw them), undistorted.
struct SpotMeasurement {
  std::vector<model::PlaneSpot> detected;  // every identified spot, distorted, by id
  std::vector<model::PlaneSpot> spots;     // identified (and undistorted, if a distortion was given), by id
  int indexed = 0;
  int unassigned = 0;                      // detections without identity (glints)
  int missing = 0;                         // designed spots not found
  std::vector<model::SpotId> missing_ids;  // the same, by id
  // Unassigned detections that may yet be identified (pipeline/surface_labelling.h), distorted detection-plane mm:
  // not flagged, and carrying the light of a spot (FreeDetectionIsSpotLike).
  std::vector<Eigen::Vector2d> free_mm;
  int undistort_failures = 0;              // identified spots outside the calibration's invertible domain
  int excluded = 0;                        // identified but flagged (near another blob, at the border): left out
  std::string orientation_message;         // the image-orientation check, one line for the measurement's output
  CaptureQuality capture;
};

// Whether an unassigned detection carries the light of a spot: its flux within kFreeFluxLow..kFreeFluxHigh of the
// median of its kFreeFluxNeighbours nearest identified spots. A glint or a lash's fragment near a hidden spot carries
// a tenth of it (0.07-0.15 measured on the all-artefact captures); a spot a lash shades in part keeps half or more
// and is left to the surface's check. True when there is none to compare with.
inline constexpr int kFreeFluxNeighbours = 4;
inline constexpr double kFreeFluxLow = 0.5, kFreeFluxHigh = 2.0;
bool FreeDetectionIsSpotLike(const correct::LocatedSpot& free, const std::vector<correct::LocatedSpot>& identified);

// Detection and identification as `topocal detect` does it: the spots located and identified, the capture assessed.
// Throws util::InputError when the image's orientation contradicts the camera's (the orientation key says so: a
// camera file that does not describe this camera), util::MeasurementRefused (one line: why, the share of the designed
// spots identified, the capture-quality line) when the pattern cannot be identified or fewer than
// kMinVisibleFraction of its spots are, util::InputError for an image type the detector cannot use.
struct IdentifiedSpots {
  correct::DetectAndIndexResult located;
  CaptureQuality capture;
};
IdentifiedSpots IdentifySpots(const cv::Mat& image, const model::TopographerCamera& camera,
                              const model::IdealImageParams& ideal, const correct::DetectAndIndexOptions& options = {});

// The identified spots of `identified` on the detection plane, undistorted with `distortion` when one is given; the
// unassigned detections that carry a spot's light (FreeDetectionIsSpotLike) kept as free detections.
SpotMeasurement MeasurementOf(const IdentifiedSpots& identified, const std::optional<model::Distortion>& distortion,
                              const correct::DetectAndIndexOptions& options = {});

// The detected (distorted) spots undistorted with `distortion`. Spots outside its invertible domain are left out;
// *failures (if given) counts them.
std::vector<model::PlaneSpot> UndistortSpots(const std::vector<model::PlaneSpot>& detected,
                                               const model::Distortion& distortion, int* failures = nullptr);

// IdentifySpots, then the identified spots on the detection plane. Throws what IdentifySpots throws.
SpotMeasurement MeasureSpots(const cv::Mat& image, const model::TopographerCamera& camera,
                             const model::IdealImageParams& ideal, const std::optional<model::Distortion>& distortion,
                             const correct::DetectAndIndexOptions& options = {});

// A raw spot image, checked against the camera's sensor size: util::InputError naming the file (and `camera_file`,
// where the size comes from) otherwise.
cv::Mat ReadSpotImage(const std::string& path, const model::TopographerCamera& camera, const std::string& camera_file);

// Through an as-built device: its camera maps pixels to the detection plane and its distortion is undone.
SpotMeasurement MeasureSpots(const cv::Mat& image, const model::Device& device, const model::IdealImageParams& ideal,
                             const correct::DetectAndIndexOptions& options = {});

// The configuration as eyes are measured with it (`reconstruct`, `detect` and the Python module): unless the
// configuration (or --surface-model) names a surface model, the spline joins where the polynomial does not fit the
// data (keratoconus, ablations; docs/reconstruction.md).
model::Config ForEyes(model::Config config);

// The analysis of undistorted spots as a measurement makes it: through `device` (AnalyzeThroughDevice) or, without
// one (a camera alone), through the configuration's design (topo::AnalyzeSpots with the designed targets).
using SpotAnalysis = std::function<topo::Analysis(const std::vector<model::PlaneSpot>&)>;
SpotAnalysis AnalysisOf(const model::Device* device, const model::Config& config, const model::BiconicParams* truth);

// Every identity of *m checked against the surface the others give and the free detections identified through it
// (LabelThroughSurface through `imaging`, the device the image was taken through), then the verdict
// (JudgeMeasurement). When the identified spots give no surface (`analyze` throws: a ray misses it, the fit fails),
// the verdict is invalid with that reason and *analysis is left empty. An invalid verdict means: no clinical number.
MeasurementVerdict LabelAndJudge(SpotMeasurement* m, const model::Device& imaging, const model::Config& config,
                                 const SpotAnalysis& analyze, topo::Analysis* analysis);

// The detection with the identities the surface's check left (`labelled`, measured from `located` and through
// LabelAndJudge): spots the surface rejected moved to `excluded` and flagged kSurfaceOutlier, free detections it
// identified moved from `unassigned` to `spots` with their identity and flagged kSurfaceLabelled, both lists kept in
// id order and `missing` without the new identities.
correct::DetectAndIndexResult WithSurfaceIdentities(const correct::DetectAndIndexResult& located,
                                                    const SpotMeasurement& labelled);

// Detection and identification as `topocal detect` and the Python module's detect() give them, the same as
// `reconstruct --image` measures with: IdentifySpots with imaging's camera, MeasurementOf (imaging's distortion
// undone when `undistort`), LabelAndJudge through `imaging` with `analyze`, WithSurfaceIdentities and, when the
// verdict is valid, CheckFlaggedIdentities. Throws what IdentifySpots throws.
struct CheckedSpots {
  correct::DetectAndIndexResult located;  // with the surface's identities
  CaptureQuality capture;
  MeasurementVerdict verdict;
  int flagged_identities_dropped = 0;  // CheckFlaggedIdentities
};

// The identities of the flagged spots (left out of the measurement, so never checked by the surface the others give)
// checked against that surface: a flagged spot keeps its identity only when, of every designed spot the surface
// images through `imaging` (PredictSpots), its own lands nearest to it, within the labelling's gate
// (kGateSpacings of the distance from there to the next prediction). Otherwise — a centre a lid's margin or a lash
// pulled towards another spot's place, or a wrong identity — the identity is dropped: the detection joins the
// unassigned blobs with its flags, its id the missing ones. Returns how many were dropped.
int CheckFlaggedIdentities(correct::DetectAndIndexResult* located, const topo::Reconstruction& surface,
                           const model::Device& imaging, const model::Config& config);
CheckedSpots DetectThroughSurface(const cv::Mat& image, const model::Device& imaging, bool undistort,
                                  const SpotAnalysis& analyze, const model::Config& config,
                                  const correct::DetectAndIndexOptions& options = {});

// Reconstruction, biconic fit and maps of undistorted spots measured through a device (topo/device_analysis.h).
using topo::AnalyzeThroughDevice;

// A raw image of an eye measured through a device as `topocal reconstruct --image --device` measures it: the spots
// detected, identified and undistorted (MeasureSpots), every spot checked against the surface the others give and
// the free detections identified through it (LabelThroughSurface, counted in spots.capture) and the verdict
// (JudgeMeasurement). An invalid verdict comes
// back with its reasons: the caller must not report the analysis's clinical numbers. Throws what MeasureSpots and
// AnalyzeThroughDevice throw.
struct EyeMeasurement {
  SpotMeasurement spots;
  topo::Analysis analysis;
  MeasurementVerdict verdict;
};
EyeMeasurement MeasureEye(const cv::Mat& image, const model::Device& device, const model::Config& config,
                          const correct::DetectAndIndexOptions& options = {},
                          const model::BiconicParams* truth = nullptr);

}  // namespace topocal::pipeline

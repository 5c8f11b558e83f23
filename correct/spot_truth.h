#pragma once
// Where each spot of a measurement lands on the sensor, with the shape of its image: the ground truth for
// rendering (correct/spot_render.h) and for testing detection and indexing.
//
// Centre: the designed target of the spot (model::DesignNullScreen), reflected by the cornea (model::SynthesizeImage),
// distorted (model::Distort), mapped to pixels by the camera.
// Shape: the spot on the null screen is the back-trace of the ideal-image circle of radius spot_radius_um about the
// ideal point P1. Its image is taken as that circle mapped through the local Jacobian J of the whole imaging
// P1 -> (backward trace to the cone) -> (reflection on the cornea) -> distortion -> pixels, J by central
// differences over the circle's own radius (four traced points). shape_px = J * radius: the spot is
// shape_px * unit disk about the centre. Spots whose neighbourhood cannot be traced keep a circle of the nominal
// radius in pixels (radius / pitch; does not happen on the paper's corneas).
#include <string>
#include <vector>

#include "correct/spot_render.h"
#include "model/config.h"
#include "model/device.h"
#include "model/distortion.h"
#include "model/null_screen.h"
#include "model/surface.h"
#include "model/topographer_camera.h"

namespace topocal::correct {

struct SpotTruth {
  std::vector<SpotToRender> spots;          // centre_px and shape_px filled; sorted by id
  std::vector<Eigen::Vector2d> position_mm;  // distorted detection-plane mm, same order
  std::vector<model::SpotFailure> failures;  // designed spots the cornea does not image
};

// Through an as-built device (model/device.h): the design's targets placed by the device's screen pose, imaged with
// its a, distorted by its lens and mapped by its camera.
SpotTruth SpotsOnSensor(const model::Surface& cornea, const model::IdealImageParams& ideal,
                        const model::TopographerParams& design, const model::Device& device);
// The same through a device whose screen sits exactly as designed (camera.a_mm is the design's a).
SpotTruth SpotsOnSensor(const model::Surface& cornea, const model::IdealImageParams& ideal,
                        const model::TopographerParams& topographer, const model::Distortion& distortion,
                        const model::TopographerCamera& camera);

// The rendered spots' ground truth as `render-spots --truth` writes it: "ring,index,x_px,y_px,x_mm,y_mm", one row
// per spot (ring 0 = glint) in the given order, pixels to 6 and detection-plane mm (distorted) to 9 decimals.
std::string SpotTruthCsv(const std::vector<SpotToRender>& spots, const model::TopographerCamera& camera);

}  // namespace topocal::correct

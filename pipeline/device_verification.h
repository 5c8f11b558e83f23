#pragma once
// What the device calibration is worth on a unit: a held-out reference ball and the paper cornea,
// each measured three ways —
//   uncorrected: through the nominal device (the perfect instrument the design describes),
//   lens only:   the lens distortion calibrated from target views, the geometry nominal (today's workflow),
//   device:      through the device calibrated from the reference balls (screen pose, principal point, a, lens).
// The held-out ball is not one of the balls the device was fitted to; it must sit at the working position (its
// vertex at the datum's z = 0, where eyes are measured), laterally anywhere.
#include <opencv2/core/mat.hpp>

#include "model/config.h"
#include "model/device.h"
#include "pipeline/unit_verification.h"
#include "util/io.h"

namespace topocal::pipeline {

struct ThreeWay {
  StageResult uncorrected, lens_only, device;
};

struct HeldOutBall {
  double radius_true_mm = 0;
  double power_true_D = 0;  // (n_k - 1) / R
  int spots_indexed = 0;
  ThreeWay stages;
};

// Throws util::InputError for a non-physical radius or an image of the wrong size, std::runtime_error (one
// line) when the spots cannot be found or a reconstruction fails.
HeldOutBall VerifyHeldOutBall(const cv::Mat& image, double radius_mm, const model::Device& nominal,
                              const model::Device& lens_only, const model::Device& calibrated,
                              const model::Config& config);

// The paper cornea imaged (exact spots) through the calibrated device — the best model of the unit — and measured
// the three ways. The device stage reproduces the truth by construction; the other two say what the unit would
// get wrong without it.
ThreeWay PaperCorneaThroughDevice(const model::Device& nominal, const model::Device& lens_only,
                                  const model::Device& calibrated, const model::Config& config);

}  // namespace topocal::pipeline

// topocal detect: the spots of a raw image, detected, indexed and flagged, with the estimator a user chooses; every
// identity checked against the surface the others give, and refused (exit 4, no spots file) when the data cannot
// support them.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <memory>
#include <optional>
#include <nlohmann/json.hpp>

#include "calib/calibration_file.h"
#include "correct/detect_and_index.h"
#include "correct/detected_spots_csv.h"
#include "imageio/image_file.h"
#include "model/config.h"
#include "model/device.h"
#include "model/topographer_camera.h"
#include "pipeline/capture_quality.h"
#include "pipeline/detection_plane.h"
#include "pipeline/measure_spots.h"
#include "report/analysis_json.h"
#include "tools/commands.h"
#include "tools/surface_option.h"
#include "util/io.h"
#include "util/json_section.h"

namespace topocal::tools {
namespace {

struct DetectArgs {
  std::string image, camera, calibration, device, config, out, json, estimator = "psf";
  ReconstructionOverrides overrides;  // the surface the identities are checked against, as reconstruct's
};

// A refused detection: only its JSON (marked invalid, with the reasons), when one was asked for.
void WriteRefusal(const DetectArgs& a, const nlohmann::json& j) {
  if (a.json.empty()) return;
  util::StagedOutputs outputs;
  outputs.AddFile(a.json, util::JsonFileText(j));
  outputs.Commit();
}

void Run(const DetectArgs& a) {
  if (a.camera.empty() == a.device.empty()) throw util::InputError("detect: give one of --camera or --device");
  auto cfg = model::LoadConfig(a.config);
  a.overrides.ApplyTo(&cfg);
  cfg = pipeline::ForEyes(cfg);
  std::optional<model::Device> device;
  if (!a.device.empty()) device = model::LoadDevice(a.device).device;
  // As reconstruct --image: through the device, or the camera's nominal device with the calibration's distortion
  // (and pixel aspect), the spots undistorted only when one of them says how.
  model::Device imaging = device ? *device : model::NominalDevice(model::LoadTopographerCamera(a.camera));
  if (!a.calibration.empty()) {
    const auto on_plane = pipeline::CalibrationOnDetectionPlane(calib::LoadCalibrationFile(a.calibration),
                                                                a.calibration, imaging.camera, a.camera);
    imaging.camera = on_plane.camera;
    imaging.distortion = on_plane.distortion;
  }
  const std::string& camera_file = a.device.empty() ? a.camera : a.device;
  correct::DetectAndIndexOptions options;
  options.detection.method = correct::CentroidMethodFromName(a.estimator);
  const cv::Mat image = ReadSpotImage(a.image, imaging.camera, camera_file);
  pipeline::CheckedSpots checked;
  try {
    checked = pipeline::DetectThroughSurface(image, imaging, device || !a.calibration.empty(),
                                             pipeline::AnalysisOf(device ? &*device : nullptr, cfg, nullptr), cfg,
                                             options);
  } catch (const std::invalid_argument& e) {
    throw util::InputError(fmt::format("{}: {}", a.image, e.what()));
  } catch (const util::InputError& e) {
    throw util::InputError(fmt::format("{}: {}", a.image, e.what()));
  } catch (const util::MeasurementRefused& e) {
    WriteRefusal(a, {{"image", a.image}, {"valid", false}, {"refused", {e.what()}}});
    throw util::MeasurementRefused(fmt::format("{}: {}", a.image, e.what()));
  }
  const correct::DetectAndIndexResult& r = checked.located;
  nlohmann::json j = report::DetectionJson(r, options.detection.method, checked.capture);
  j["image"] = a.image;
  j["valid"] = checked.verdict.valid;
  j["flagged_identities_dropped"] = checked.flagged_identities_dropped;
  if (!checked.verdict.valid) {
    // Identities the data cannot support are not written: the JSON says why, the spots file is not made.
    j["refused"] = checked.verdict.reasons;
    WriteRefusal(a, j);
    fmt::print("{}\n", checked.capture.Line());
    fmt::print("spot identities REFUSED (no spots file written):\n");
    for (const auto& reason : checked.verdict.reasons) fmt::print("  - {}\n", reason);
    throw util::MeasurementRefused(
        fmt::format("{}: spot identities refused: {}", a.image, fmt::join(checked.verdict.reasons, "; ")));
  }
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out, correct::DetectedSpotsCsv(r));
  if (!a.json.empty()) outputs.AddFile(a.json, util::JsonFileText(j));
  outputs.Commit();
  fmt::print("detect ({}): {} spots indexed ({} flagged and left out of a measurement: near a blob, at the border, "
             "on an uneven background, a flux outlier or rejected by the surface the others give; {} identified "
             "through that surface; {} flagged spots' identities dropped, their own spot not the nearest the surface "
             "predicts), {} unassigned blobs, {} designed spots missing -> {}\n",
             j["estimator"].get<std::string>(), r.spots.size() + r.excluded.size(), r.excluded.size(),
             checked.capture.surface_labelled, checked.flagged_identities_dropped, r.unassigned.size(),
             r.missing.size(), a.out);
  fmt::print("{}\n", r.orientation.message);
  fmt::print("{}\n", checked.capture.Line());
}

}  // namespace

cv::Mat ReadSpotImage(const std::string& path, const model::TopographerCamera& camera, const std::string& camera_file) {
  cv::Mat image = imageio::ReadImage(path, imageio::Channels::kAsStored);
  imageio::RequireSize(image, path, camera.width_px, camera.height_px, camera_file);
  return image;
}

void AddDetectCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("detect",
                                 "Detect, index and flag the spots of a raw image, every identity checked against the "
                                 "surface the others give (CSV + JSON summary; exit 4 and no CSV when refused)");
  auto a = std::make_shared<DetectArgs>();
  cmd->add_option("--image", a->image, "Raw sensor image of the spots")->required();
  auto* camera = cmd->add_option("--camera", a->camera, "Topographer camera (JSON, docs/camera-conventions.md)");
  auto* device = cmd->add_option("--device", a->device, "Device (JSON, docs/device.md): its camera is used");
  auto* calibration = cmd->add_option("--calibration", a->calibration,
                                      "Lens calibration (YAML) of the --camera: the spots are checked undistorted, as "
                                      "reconstruct --calibration measures them");
  camera->excludes(device);
  calibration->needs(camera);
  cmd->add_option("--config", a->config, "Topographer configuration (JSON)")->required();
  cmd->add_option("--out", a->out, "Spots CSV: ring,index,x_mm,y_mm,u_px,v_px,flags (ring 0: unassigned blob)")
      ->required();
  cmd->add_option("--json", a->json, "Summary JSON: counts, missing identities, noise model, orientation");
  cmd->add_option("--estimator", a->estimator, "Spot centre estimator: psf (default), centroid or gaussian")
      ->check(CLI::IsMember({"psf", "centroid", "gaussian"}))
      ->capture_default_str();
  a->overrides.AddTo(cmd);
  cmd->callback([a] { Run(*a); });
}

}  // namespace topocal::tools

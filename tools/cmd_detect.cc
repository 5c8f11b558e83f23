// topocal detect: the spots of a raw image, detected, indexed and flagged, with the estimator a user chooses.
#include <fmt/format.h>

#include <memory>
#include <nlohmann/json.hpp>

#include "correct/detect_and_index.h"
#include "correct/detected_spots_csv.h"
#include "imageio/image_file.h"
#include "model/config.h"
#include "model/device.h"
#include "model/topographer_camera.h"
#include "pipeline/capture_quality.h"
#include "pipeline/measure_spots.h"
#include "report/analysis_json.h"
#include "tools/commands.h"
#include "util/io.h"
#include "util/json_section.h"

namespace topocal::tools {
namespace {

struct DetectArgs {
  std::string image, camera, device, config, out, json, estimator = "psf";
};

void Run(const DetectArgs& a) {
  if (a.camera.empty() == a.device.empty()) throw util::InputError("detect: give one of --camera or --device");
  const auto cfg = model::LoadConfig(a.config);
  const auto camera = a.device.empty() ? model::LoadTopographerCamera(a.camera) : model::LoadDevice(a.device).device.camera;
  const std::string& camera_file = a.device.empty() ? a.camera : a.device;
  correct::DetectAndIndexOptions options;
  options.detection.method = correct::CentroidMethodFromName(a.estimator);
  const cv::Mat image = ReadSpotImage(a.image, camera, camera_file);
  pipeline::IdentifiedSpots identified;
  try {
    identified = pipeline::IdentifySpots(image, camera, cfg.ideal_image, options);
  } catch (const std::invalid_argument& e) {
    throw util::InputError(fmt::format("{}: {}", a.image, e.what()));
  } catch (const util::InputError& e) {
    throw util::InputError(fmt::format("{}: {}", a.image, e.what()));
  } catch (const util::MeasurementRefused& e) {
    throw util::MeasurementRefused(fmt::format("{}: {}", a.image, e.what()));
  }
  const correct::DetectAndIndexResult& r = identified.located;
  const pipeline::CaptureQuality& capture = identified.capture;
  nlohmann::json j = report::DetectionJson(r, options.detection.method, capture);
  j["image"] = a.image;
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out, correct::DetectedSpotsCsv(r));
  if (!a.json.empty()) outputs.AddFile(a.json, util::JsonFileText(j));
  outputs.Commit();
  fmt::print("detect ({}): {} spots indexed ({} flagged and left out of a measurement: near a blob, at the border, "
             "on an uneven background or a flux outlier), {} unassigned blobs, {} designed spots missing -> {}\n",
             j["estimator"].get<std::string>(), r.spots.size() + r.excluded.size(), r.excluded.size(),
             r.unassigned.size(), r.missing.size(), a.out);
  fmt::print("{}\n", r.orientation.message);
  fmt::print("{}\n", capture.Line());
}

}  // namespace

cv::Mat ReadSpotImage(const std::string& path, const model::TopographerCamera& camera, const std::string& camera_file) {
  cv::Mat image = imageio::ReadImage(path, imageio::Channels::kAsStored);
  imageio::RequireSize(image, path, camera.width_px, camera.height_px, camera_file);
  return image;
}

void AddDetectCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("detect", "Detect, index and flag the spots of a raw image (CSV + JSON summary)");
  auto a = std::make_shared<DetectArgs>();
  cmd->add_option("--image", a->image, "Raw sensor image of the spots")->required();
  auto* camera = cmd->add_option("--camera", a->camera, "Topographer camera (JSON, docs/camera-conventions.md)");
  auto* device = cmd->add_option("--device", a->device, "Device (JSON, docs/device.md): its camera is used");
  camera->excludes(device);
  cmd->add_option("--config", a->config, "Topographer configuration (JSON)")->required();
  cmd->add_option("--out", a->out, "Spots CSV: ring,index,x_mm,y_mm,u_px,v_px,flags (ring 0: unassigned blob)")
      ->required();
  cmd->add_option("--json", a->json, "Summary JSON: counts, missing identities, noise model, orientation");
  cmd->add_option("--estimator", a->estimator, "Spot centre estimator: psf (default), centroid or gaussian")
      ->check(CLI::IsMember({"psf", "centroid", "gaussian"}))
      ->capture_default_str();
  cmd->callback([a] { Run(*a); });
}

}  // namespace topocal::tools

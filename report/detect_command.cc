#include "report/detect_command.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <optional>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "correct/detect_and_index.h"
#include "correct/detected_spots_csv.h"
#include "model/device.h"
#include "pipeline/capture_quality.h"
#include "pipeline/lens_device.h"
#include "pipeline/measure_spots.h"
#include "report/analysis_json.h"
#include "util/io.h"
#include "util/json_section.h"

namespace topocal::report {
namespace {

// A refused detection: only its JSON (marked invalid, with the reasons), when one was asked for.
void WriteRefusal(const DetectRequest& a, const nlohmann::json& j) {
  if (a.json_path.empty()) return;
  util::StagedOutputs outputs;
  outputs.AddFile(a.json_path, util::JsonFileText(j));
  outputs.Commit();
}

// Identities the data cannot support are not written: the JSON says why, the spots file is not made.
[[noreturn]] void RefuseIdentities(const DetectRequest& a, const pipeline::CheckedSpots& checked, nlohmann::json j,
                                   std::ostream& out) {
  j["refused"] = checked.verdict.reasons;
  WriteRefusal(a, j);
  out << checked.capture.Line() << "\n";
  out << "spot identities REFUSED (no spots file written):\n";
  for (const auto& reason : checked.verdict.reasons) out << fmt::format("  - {}\n", reason);
  throw util::MeasurementRefused(
      fmt::format("{}: spot identities refused: {}", a.image_path, fmt::join(checked.verdict.reasons, "; ")));
}

}  // namespace

void RunDetect(const DetectRequest& a, std::ostream& out) {
  if (a.device_path.empty()) throw util::InputError("detect: give --device (the device the image was taken through)");
  auto cfg = model::LoadConfig(a.config_path);
  if (a.override_config) a.override_config(&cfg);
  cfg = pipeline::ForEyes(cfg);
  // As reconstruct --image: through the device, with the calibration's lens on it when one is given.
  const model::Device imaging = pipeline::LoadMeasuringDevice(a.device_path, a.calibration_path).device;
  correct::DetectAndIndexOptions options;
  options.detection.method = correct::CentroidMethodFromName(a.estimator);
  const cv::Mat image = pipeline::ReadSpotImage(a.image_path, imaging.camera, a.device_path);
  pipeline::CheckedSpots checked;
  try {
    checked =
        pipeline::DetectThroughSurface(image, imaging, true, pipeline::AnalysisOf(&imaging, cfg, nullptr), cfg, options);
  } catch (const util::InputError& e) {
    throw util::InputError(fmt::format("{}: {}", a.image_path, e.what()));
  } catch (const util::MeasurementRefused& e) {
    WriteRefusal(a, {{"image", a.image_path}, {"valid", false}, {"refused", {e.what()}}});
    throw util::MeasurementRefused(fmt::format("{}: {}", a.image_path, e.what()));
  }
  const correct::DetectAndIndexResult& r = checked.located;
  nlohmann::json j = DetectionJson(r, options.detection.method, checked.capture);
  j["image"] = a.image_path;
  j["valid"] = checked.verdict.valid;
  j["flagged_identities_dropped"] = checked.flagged_identities_dropped;
  if (!checked.verdict.valid) RefuseIdentities(a, checked, j, out);
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out_path, correct::DetectedSpotsCsv(r));
  if (!a.json_path.empty()) outputs.AddFile(a.json_path, util::JsonFileText(j));
  outputs.Commit();
  out << fmt::format(
      "detect ({}): {} spots indexed ({} flagged and left out of a measurement: near a blob, at the border, "
      "on an uneven background, a flux outlier or rejected by the surface the others give; {} identified "
      "through that surface; {} flagged spots' identities dropped, their own spot not the nearest the surface "
      "predicts), {} unassigned blobs, {} designed spots missing -> {}\n",
      j["estimator"].get<std::string>(), r.spots.size() + r.excluded.size(), r.excluded.size(),
      checked.capture.surface_labelled, checked.flagged_identities_dropped, r.unassigned.size(), r.missing.size(),
      a.out_path);
  out << r.orientation.message << "\n";
  out << checked.capture.Line() << "\n";
}

}  // namespace topocal::report

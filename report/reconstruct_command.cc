#include "report/reconstruct_command.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <optional>
#include <stdexcept>
#include <vector>

#include <nlohmann/json.hpp>

#include "correct/detect_and_index.h"
#include "model/device.h"
#include "model/null_screen.h"
#include "model/spots_csv.h"
#include "pipeline/capture_quality.h"
#include "pipeline/lens_device.h"
#include "pipeline/map_output.h"
#include "pipeline/measure_spots.h"
#include "pipeline/measurement_uncertainty.h"
#include "pipeline/surface_labelling.h"
#include "plot/map_image.h"
#include "report/analysis_json.h"
#include "topo/analysis.h"
#include "util/io.h"
#include "util/json_section.h"
#include "util/new_directory_guard.h"

namespace topocal::report {
namespace {

// "value +- U" of a reported quantity (GUM: U to two digits, k = 2 stated once) when `u` has it, otherwise
// "value +- sd" with the fit's standard deviation as before (no device: the fit's own figure).
class Printer {
 public:
  explicit Printer(const pipeline::MeasurementUncertainty* u) : u_(u) {}
  std::string operator()(const std::string& name, double value, double sd, int decimals) const {
    if (u_) return (*this)(name, value, decimals);
    return fmt::format("{:.{}f} +- {:.{}f}", value, decimals, sd, decimals);
  }
  std::string operator()(const std::string& name, double value, int decimals) const {
    if (const auto* q = u_ ? u_->Find(name) : nullptr) {
      return pipeline::FormatWithUncertainty(value, q->expanded, decimals) + (q->lower_bound ? "*" : "");
    }
    return fmt::format("{:.{}f}", value, decimals);
  }
  // "at (x, y) mm" of a peak whose location is read as <prefix>x_mm, <prefix>y_mm; a location the data do not
  // determine (a second peak within the value's U) is said so, without numbers.
  std::string At(const std::string& prefix, const Eigen::Vector2d& at) const {
    if (const auto* q = u_ ? u_->Find(prefix + "x_mm") : nullptr; q && !q->determined) {
      return "at a location not determined (a second peak 1 mm or more away lies within U)";
    }
    return fmt::format("at ({}, {}) mm", (*this)(prefix + "x_mm", at.x(), 2), (*this)(prefix + "y_mm", at.y(), 2));
  }

 private:
  const pipeline::MeasurementUncertainty* u_;
};

void PrintUncertaintySources(const pipeline::MeasurementUncertainty& u, std::ostream& out) {
  out << fmt::format("uncertainties below are U (k = 2) from: ");
  if (!u.device_covariance) {
    out << fmt::format("NOT the device ({}), ", u.no_device_covariance);
  } else if (u.device_monte_carlo) {
    out << fmt::format("the device's covariance ({} Monte Carlo draws of {} parameter{}), ", u.device_analyses,
                       u.device_parameters.size(), u.device_parameters.size() == 1 ? "" : "s");
  } else {
    const size_t n = u.device_parameters.size();
    out << fmt::format("the device's covariance ({} parameter{}, linear along {} direction{}), ", n,
                       n == 1 ? "" : "s", u.device_directions, u.device_directions == 1 ? "" : "s");
  }
  out << fmt::format(
      "the spot-centre noise measured in this image ({:.3g} um = {:.2f} x the configured {:.3g} um, what the "
      "surface model leaves unexplained included; {} draws){}; the map's sampling\n",
      u.spot_sigma_um, u.spot_sigma_um / u.configured_spot_sigma_um, u.configured_spot_sigma_um, u.spot_draws,
      u.failed_draws > 0 ? fmt::format("; {} analyses failed", u.failed_draws) : std::string());
  const bool lower_bounds =
      std::any_of(u.quantities.begin(), u.quantities.end(), [](const auto& q) { return q.lower_bound; });
  if (lower_bounds) {
    out << fmt::format(
        "  * U a lower bound: the spline surface smooths a map's peaks and ranges by an amount the noise "
        "draws do not reveal (docs/uncertainty.md)\n");
  }
}

void PrintAnalysis(const topo::Analysis& a, const pipeline::MeasurementUncertainty* u, std::ostream& out) {
  const auto& r = a.reconstruction;
  const auto& f = a.surface_fit;
  const auto& p = f.params;
  const Printer v(u);
  out << fmt::format("reconstruction: {}\n", r.message);
  if (!r.unmatched.empty()) out << fmt::format("spots not in the design (ignored): {}\n", r.unmatched.size());
  if (u) PrintUncertaintySources(*u, out);
  out << fmt::format("biconic fit ({}, {} points, rms {:.4f} um):\n", topo::BiconicFitModeName(f.mode), f.points,
                     f.rms_residual_um);
  const auto& sd = f.stddev;
  out << fmt::format("  rx = {} mm   ry = {} mm\n", v("surface_fit.rx_mm", p.rx_mm, sd.rx_mm, 4),
                     v("surface_fit.ry_mm", p.ry_mm, sd.ry_mm, 4));
  out << fmt::format("  kx = {}      ky = {}\n", v("surface_fit.kx", p.kx, sd.kx, 4),
                     v("surface_fit.ky", p.ky, sd.ky, 4));
  out << fmt::format("  alpha = {} deg   vertex = {} um\n", v("surface_fit.alpha_deg", p.alpha_deg, sd.alpha_deg, 4),
                     v("surface_fit.vertex_um", p.z0_mm * 1e3, sd.z0_mm * 1e3, 4));
  if (f.mode != topo::BiconicFitMode::kPaper) {
    out << fmt::format("  apex at ({}, {}) mm: decentration {} mm\n",
                       v("surface_fit.apex_x_mm", f.apex_mm.x(), sd.apex_x_mm, 4),
                       v("surface_fit.apex_y_mm", f.apex_mm.y(), sd.apex_y_mm, 4),
                       v("surface_fit.decentration_mm", f.DecentrationMm(), 4));
  }
  if (f.mode == topo::BiconicFitMode::kFreeApex) {
    out << fmt::format("  tilt x = {} deg, y = {} deg: {} deg off the axis\n",
                       v("surface_fit.tilt_x_deg", p.tilt_x_deg, sd.tilt_x_deg, 3),
                       v("surface_fit.tilt_y_deg", p.tilt_y_deg, sd.tilt_y_deg, 3),
                       v("surface_fit.tilt_deg", f.TiltDeg(), 3));
  }
  out << fmt::format(
      "power maps (R = {:.2f} mm, points reach {:.2f} mm, every direction {:.2f} mm): pv tangential {} D, "
      "pv axial {} D\n",
      a.power.radius_mm, a.covered_radius_mm, a.supported_radius_mm,
      v("power.pv_tangential_D", a.power.pv_tangential_D, 3), v("power.pv_axial_D", a.power.pv_axial_D, 3));
  if (a.errors)
    out << fmt::format("against the configured cornea: pv {:.4f} um, rms {:.4f} um\n", a.errors->pv_um,
                       a.errors->rms_um);
  out << fmt::format(
      "model adequacy: slope residual {:.3g} = {:.2f} x the {:.3g} expected from spot-centre noise; "
      "neighbour correlation {:.2f}, shared part {:.2f} x\n",
      r.rms_slope_residual, r.adequacy_ratio, r.expected_slope_noise, r.residual_neighbour_correlation,
      r.structured_residual_ratio);
  out << fmt::format("surface model: {}{}\n", r.surface_model,
                     r.surface_model_reason.empty() ? "" : " (" + r.surface_model_reason + ")");
  if (a.clinical_ok) {
    const auto& c = a.clinical;
    out << fmt::format("clinical (data to {:.2f} mm): sim-K {} D @ {} deg / {} D @ {} deg; Kmax {} D {}\n",
                       c.supported_radius_mm, v("clinical.sim_k.steep_D", c.steep_k_D, 2),
                       v("clinical.sim_k.steep_axis_deg", c.steep_axis_deg, 0),
                       v("clinical.sim_k.flat_D", c.flat_k_D, 2), v("clinical.sim_k.flat_axis_deg", c.flat_axis_deg, 0),
                       v("clinical.kmax.power_D", c.kmax_D, 2), v.At("clinical.kmax.", c.kmax_at_mm));
    out << fmt::format("  BFS {} mm over {:.2f} mm: elevation peak {} um {}{}\n",
                       v("clinical.best_fit_sphere.radius_mm", c.bfs_radius_mm, 3), c.bfs_zone_radius_mm,
                       v("clinical.best_fit_sphere.elevation_peak_um", c.elevation_peak_um, 2),
                       v.At("clinical.best_fit_sphere.elevation_peak_", c.elevation_peak_at_mm),
                       c.is_available
                           ? fmt::format("; I-S {} D", v("clinical.inferior_superior_D", c.inferior_superior_D, 2))
                           : std::string());
  } else {
    out << fmt::format("clinical indices: {}\n", a.clinical_message);
  }
  for (const auto& w : a.warnings) out << fmt::format("WARNING: {}\n", w);
}

// pipeline::MeasureSpots with the user's estimator; its failures name the image.
pipeline::SpotMeasurement MeasureImage(const cv::Mat& image, const model::TopographerCamera& camera,
                                       const model::IdealImageParams& ideal,
                                       const std::optional<model::Distortion>& distortion, const ReconstructRequest& in,
                                       std::ostream& out) {
  correct::DetectAndIndexOptions options;
  options.detection.method = correct::CentroidMethodFromName(in.estimator);
  pipeline::SpotMeasurement m;
  try {
    m = pipeline::MeasureSpots(image, camera, ideal, distortion, options);
  } catch (const util::InputError& e) {
    throw util::InputError(fmt::format("{}: {}", in.image_path, e.what()));
  } catch (const util::MeasurementRefused& e) {
    throw util::MeasurementRefused(fmt::format("{}: {}", in.image_path, e.what()));
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: {}", in.image_path, e.what()));
  }
  out << fmt::format("{}\n", m.orientation_message);
  if (m.excluded > 0)
    out << fmt::format(
        "{} identified spots flagged (near another blob, at the border, on an uneven background or a flux "
        "outlier): left out\n",
        m.excluded);
  return m;
}

// Spots from a CSV, or detected, indexed and undistorted in a raw image through the measuring device.
// From an image, *from_image is the measurement (the device it was measured through is `device`).
std::vector<model::PlaneSpot> ReadMeasurement(const ReconstructRequest& in, const model::Config& cfg,
                                                const pipeline::MeasuringDevice* device, nlohmann::json* info,
                                                std::optional<pipeline::SpotMeasurement>* from_image,
                                                std::ostream& out) {
  if (!in.spots_path.empty()) {
    auto measured = model::ReadSpotsCsv(in.spots_path);
    (*info)["spots_read"] = measured.size();
    return measured;
  }
  const cv::Mat image = pipeline::ReadSpotImage(in.image_path, device->device.camera, in.device_path);
  const auto m = MeasureImage(image, device->device.camera, cfg.ideal_image, device->device.distortion, in, out);
  out << fmt::format(
      "image: {} spots indexed, {} unassigned detections, {} designed spots missing, measured through the "
      "device {} ({} outside its distortion's domain)\n",
      m.indexed, m.unassigned, m.missing, device->name, m.undistort_failures);
  (*info)["image"] = {{"indexed", m.indexed},
                      {"unassigned", m.unassigned},
                      {"missing", m.missing},
                      {"device", in.device_path},
                      {"undistort_failures", m.undistort_failures}};
  if (!in.calibration_path.empty()) (*info)["image"]["calibration"] = in.calibration_path;
  *from_image = m;
  return m.spots;
}

// A measurement the data cannot support: its reasons on stdout and in the JSON (marked invalid, no clinical
// number), no maps, exit 4. Without `out`, the one reason is already a whole line naming the image: it is the message.
[[noreturn]] void RefuseMeasurement(const std::string& image, const pipeline::MeasurementVerdict& verdict,
                                    nlohmann::json info, const std::string& json_out, std::ostream* out) {
  info["valid"] = false;
  info["refused"] = verdict.reasons;
  if (!out) {
    if (!json_out.empty()) {
      util::StagedOutputs outputs;
      outputs.AddFile(json_out, util::JsonFileText(info));
      outputs.Commit();
    }
    throw util::MeasurementRefused(verdict.reasons.front());
  }
  *out << "measurement REFUSED (no clinical number is given):\n";
  for (const auto& r : verdict.reasons) *out << fmt::format("  - {}\n", r);
  if (!json_out.empty()) {
    util::StagedOutputs outputs;
    outputs.AddFile(json_out, util::JsonFileText(info));
    outputs.Commit();
  }
  throw util::MeasurementRefused(fmt::format("{}: measurement refused: {}", image, fmt::join(verdict.reasons, "; ")));
}

// --power-scale and --power-step as the maps' power scale (docs/maps.md, "Scales").
plot::MapScaleRequest PowerScaleOf(const ReconstructRequest& in) {
  if (in.power_step_D != 0 && in.power_scale != "fit") {
    throw util::InputError(
        "--power-step: goes with --power-scale fit (the standard and extended scales have their own)");
  }
  if (in.power_scale == "extended") return plot::ExtendedPowerScale();
  if (in.power_scale == "fit") {
    const double step = in.power_step_D == 0 ? 0.5 : in.power_step_D;
    if (!(step >= 0.05 && step <= 5.0)) throw util::InputError("--power-step: must be 0.05 to 5 D");
    return plot::FittedStepScale(step);
  }
  return plot::StandardPowerScale();
}

// The U of every number measured through a device (its "uncertainty" JSON block in `info`); the measurement is
// refused when the U cannot be evaluated or leaves no clinical reading (pipeline::UncertaintyRefusal).
pipeline::MeasurementUncertainty UncertaintyOrRefusal(
    const ReconstructRequest& in, const std::vector<model::PlaneSpot>& detected,
    const pipeline::MeasuringDevice& device, const model::Config& cfg, const topo::Analysis& analysis,
    nlohmann::json* info, const std::string& json_out, std::ostream& out) {
  pipeline::UncertaintyOptions u_options;
  u_options.device_draws = in.uncertainty_samples;
  u_options.seed = in.seed;
  pipeline::MeasurementUncertainty u;
  try {
    const auto shown = util::StartProgress(in.uncertainty_samples > 0 ? in.progress : util::ShowProgress(),
                                           fmt::format("{} device draws", in.uncertainty_samples));
    u = pipeline::PropagateMeasurementUncertainty(detected, device.device, device.covariance, cfg, analysis,
                                                  u_options);
    u.no_device_covariance = device.no_covariance;
  } catch (const std::runtime_error& e) {
    RefuseMeasurement(in.image_path, {false, {fmt::format("its uncertainty cannot be evaluated: {}", e.what())}}, *info,
                      json_out, &out);
  }
  (*info)["uncertainty"] = MeasurementUncertaintyJson(u);
  if (const auto reason = pipeline::UncertaintyRefusal(u)) {
    RefuseMeasurement(in.image_path, {false, {*reason}}, *info, json_out, &out);
  }
  return u;
}

// The configuration with the request's overrides, for measuring eyes.
model::Config ReconstructionConfig(const ReconstructRequest& request) {
  auto cfg = model::LoadConfig(request.config_path);
  if (request.override_config) request.override_config(&cfg);
  return pipeline::ForEyes(cfg);  // the verb that measures eyes
}

// From an image: the capture-quality line, and the measurement refused when the verdict is invalid.
std::optional<pipeline::CaptureQuality> JudgeCapture(const std::optional<pipeline::SpotMeasurement>& from_image,
                                                     const pipeline::MeasurementVerdict& verdict,
                                                     const std::string& image, nlohmann::json& info,
                                                     const std::string& json_out, std::ostream& out) {
  const std::optional<pipeline::CaptureQuality> capture =
      from_image ? std::optional(from_image->capture) : std::nullopt;
  if (capture) {
    out << fmt::format("{}\n", capture->Line());
    info["capture"] = CaptureJson(*capture);
    info["valid"] = verdict.valid;
    if (!verdict.valid) RefuseMeasurement(image, verdict, info, json_out, &out);
  }
  return capture;
}

// The maps of the analysis, with the U of the axial power and the peaks' determination when measured through a
// device.
void AddMaps(util::StagedOutputs& outputs, const std::string& maps, const ReconstructRequest& in,
             const plot::MapScaleRequest& power_scale, const topo::Analysis& analysis,
             const model::BiconicParams* truth_cornea,
             const std::optional<pipeline::MeasurementUncertainty>& measurement_u,
             const std::optional<pipeline::CaptureQuality>& capture) {
  pipeline::MapSetOptions map_options;
  map_options.eye = in.eye;  // N/T/S/I on the maps, in the examiner's view
  map_options.power = power_scale;
  map_options.overview = true;  // overview.png: the three maps, the clinical numbers and the capture's quality
  if (capture) map_options.overview_lines.push_back(capture->Line());
  pipeline::AnalysisMapEntry entry{"", "", &analysis, truth_cornea, {}};
  if (measurement_u) {
    entry.axial_expanded_D = &measurement_u->axial_expanded_D;
    const auto determined = [&](const char* name) {
      const auto* q = measurement_u->Find(name);
      return !q || q->determined;
    };
    entry.kmax_location_determined = determined("clinical.kmax.x_mm");
    entry.elevation_peak_location_determined = determined("clinical.best_fit_sphere.elevation_peak_x_mm");
  }
  pipeline::WriteAnalysisMapSet(outputs.AddDirectory(maps), {entry}, map_options);
}

}  // namespace

void RunReconstruct(const ReconstructRequest& request, std::ostream& out) {
  const util::NewDirectoryGuard maps_guard(request.maps_dir);  // a failed run leaves no empty --maps folder
  const plot::MapScaleRequest power_scale = PowerScaleOf(request);  // bad options refused before any work
  auto cfg = ReconstructionConfig(request);
  ReconstructRequest in = request;
  if (in.eye.empty()) in.eye = cfg.eye;  // the eye: the request's, else the configuration's
  const std::string& json_out = in.json_path;
  const std::string& maps = in.maps_dir;
  const bool truth = in.truth;
  if (in.spots_path.empty() == in.image_path.empty())
    throw util::InputError("reconstruct: give one of --spots or --image");
  if (!in.spots_path.empty() && (!in.device_path.empty() || !in.calibration_path.empty())) {
    throw util::InputError("--device and --calibration go with --image (a spots CSV is already in mm)");
  }
  if (!in.image_path.empty() && in.device_path.empty()) {
    throw util::InputError("--image: needs --device (the camera, distortion and screen pose it was taken through)");
  }
  if (in.uncertainty_samples > 0 && in.image_path.empty()) throw util::InputError("--uncertainty needs --image");
  nlohmann::json info;
  if (!in.eye.empty()) info["eye"] = in.eye;
  std::optional<pipeline::MeasuringDevice> device;
  if (!in.device_path.empty()) device = pipeline::LoadMeasuringDevice(in.device_path, in.calibration_path);
  std::optional<pipeline::SpotMeasurement> from_image;
  std::vector<model::PlaneSpot> measured;
  try {
    measured = ReadMeasurement(in, cfg, device ? &*device : nullptr, &info, &from_image, out);
  } catch (const util::MeasurementRefused& e) {  // the spots could not be identified: the JSON says so too
    RefuseMeasurement(in.image_path, {false, {e.what()}}, info, json_out, nullptr);
  }
  const auto analyze =
      pipeline::AnalysisOf(device ? &device->device : nullptr, cfg, truth ? &cfg.cornea : nullptr);
  // From an image, every spot is checked against the surface the others give, and the surface identifies the
  // detections the pattern's lattice left free (capture-quality line: rejected, identified through it).
  topo::Analysis analysis;
  pipeline::MeasurementVerdict verdict;
  if (from_image) {
    verdict = pipeline::LabelAndJudge(&*from_image, device->device, cfg, analyze, &analysis);
  } else {
    analysis = analyze(measured);
  }
  const std::optional<pipeline::CaptureQuality> capture =
      JudgeCapture(from_image, verdict, in.image_path, info, json_out, out);
  // Through a device, every reported number carries its U: the device's covariance, this image's spot noise, the
  // fit's residual (pipeline/measurement_uncertainty.h).
  std::optional<pipeline::MeasurementUncertainty> measurement_u;
  if (device && capture) {
    measurement_u = UncertaintyOrRefusal(in, from_image->detected, *device, cfg, analysis, &info, json_out, out);
  }
  PrintAnalysis(analysis, measurement_u ? &*measurement_u : nullptr, out);
  util::StagedOutputs outputs;  // the JSON and the maps are published together or not at all
  if (!json_out.empty()) {
    nlohmann::json j = info;
    j.update(MeasurementJson(analysis, truth));
    if (measurement_u) WithdrawUndetermined(*measurement_u, &j);
    outputs.AddFile(json_out, util::JsonFileText(j));
  }
  if (!maps.empty()) {
    AddMaps(outputs, maps, in, power_scale, analysis, truth ? &cfg.cornea : nullptr, measurement_u, capture);
  }
  outputs.Commit();
}

}  // namespace topocal::report

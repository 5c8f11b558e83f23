// topocal.detect and topocal.reconstruct: the spots of a raw image, and the cornea measured from them — the same
// library calls as `topocal detect` and `topocal reconstruct --device`, the same numbers.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>

#include "correct/detected_spots_csv.h"
#include "imageio/image_file.h"
#include "model/null_screen.h"
#include "pipeline/map_output.h"
#include "pipeline/measurement_uncertainty.h"
#include "pipeline/measure_spots.h"
#include "python/src/py_common.h"
#include "report/analysis_json.h"
#include "topo/analysis.h"
#include "util/io.h"

namespace topocal::python {

// One row of the detected-spots table (correct/detected_spots_csv.h): the dtype of detect()'s structured array.
struct SpotRow {
  std::int32_t ring, index;
  double x_mm, y_mm, u_px, v_px;
  std::uint32_t flags;
};

namespace {

correct::DetectAndIndexOptions OptionsFor(const std::string& estimator) {
  correct::DetectAndIndexOptions options;
  options.detection.method = correct::CentroidMethodFromName(estimator);
  return options;
}

cv::Mat SensorImage(const py::array& image, const model::TopographerCamera& camera) {
  cv::Mat view = ImageView(image, "image");
  imageio::RequireSize(view, "image", camera.width_px, camera.height_px, "the device");
  return view;
}

py::array SpotTable(const correct::DetectAndIndexResult& r) {
  const auto rows = correct::DetectedSpotRows(r);
  py::array_t<SpotRow> out(static_cast<py::ssize_t>(rows.size()));
  // The row's padding (4 bytes after flags) zeroed too: the same spots give the same bytes.
  std::memset(out.mutable_data(), 0, rows.size() * sizeof(SpotRow));
  auto v = out.mutable_unchecked<1>();
  for (size_t i = 0; i < rows.size(); ++i) {
    const auto& s = rows[i];
    v(i) = {s.id.ring, s.id.index, s.position_mm.x(), s.position_mm.y(), s.position_px.x(), s.position_px.y(), s.flags};
  }
  return out;
}

py::object Detect(const py::array& image, const py::object& device, const py::object& config,
                  const std::string& estimator, bool return_summary) {
  const model::DeviceFile dev = DeviceArg(device);
  const model::Config cfg = pipeline::ForEyes(ConfigArg(config));  // the identities checked as reconstruct checks them
  const auto options = OptionsFor(estimator);
  const cv::Mat view = SensorImage(image, dev.device.camera);
  pipeline::CheckedSpots checked;
  try {
    py::gil_scoped_release release;
    checked = pipeline::DetectThroughSurface(view, dev.device, /*undistort=*/true,
                                             pipeline::AnalysisOf(&dev.device, cfg, nullptr), cfg, options);
  } catch (const util::MeasurementRefused& e) {
    RaiseRefused(e.what(), {e.what()}, {{"valid", false}, {"refused", {e.what()}}});
  }
  nlohmann::json summary = report::DetectionJson(checked.located, options.detection.method, checked.capture);
  summary["valid"] = checked.verdict.valid;
  summary["flagged_identities_dropped"] = checked.flagged_identities_dropped;
  if (!checked.verdict.valid) {
    summary["refused"] = checked.verdict.reasons;
    RaiseRefused(fmt::format("spot identities refused: {}", fmt::join(checked.verdict.reasons, "; ")),
                 checked.verdict.reasons, summary);
  }
  py::array table = SpotTable(checked.located);
  if (!return_summary) return table;
  return py::make_tuple(table, ToPython(summary));
}

// A spots table (structured array with ring, index, x_mm, y_mm, or what detect() returns) as measured spots; rows of
// ring 0 (blobs without identity) are left out, as the CLI's spots CSV reader leaves them, and so are rows whose
// flags (when the table has them) leave the spot out of a measurement: flagged near a blob, truncated, a flux
// outlier, on an uneven background or rejected by the surface.
std::vector<model::PlaneSpot> SpotsFrom(const py::array& spots) {
  const py::object names = spots.dtype().attr("names");
  if (names.is_none()) throw util::InputError("spots: need a structured array with fields ring, index, x_mm, y_mm");
  for (const char* field : {"ring", "index", "x_mm", "y_mm"}) {
    if (!py::cast<py::tuple>(names).contains(field)) throw util::InputError(fmt::format("spots: no field '{}'", field));
  }
  const py::object np = py::module_::import("numpy");
  const auto column = [&](const char* field, const py::object& dtype) {
    return np.attr("ascontiguousarray")(spots[field], dtype);
  };
  const auto ring = column("ring", np.attr("int64")).cast<py::array_t<std::int64_t>>();
  const auto index = column("index", np.attr("int64")).cast<py::array_t<std::int64_t>>();
  const auto x = column("x_mm", np.attr("float64")).cast<py::array_t<double>>();
  const auto y = column("y_mm", np.attr("float64")).cast<py::array_t<double>>();
  const bool flagged = py::cast<py::tuple>(names).contains("flags");
  const auto flags = flagged ? column("flags", np.attr("uint32")).cast<py::array_t<std::uint32_t>>()
                             : py::array_t<std::uint32_t>(ring.size());
  const unsigned left_out = correct::DetectAndIndexOptions{}.exclude_flags | correct::kSurfaceOutlier;
  std::vector<model::PlaneSpot> out;
  for (py::ssize_t i = 0; i < ring.size(); ++i) {
    if (ring.at(i) == 0 || (flagged && (flags.at(i) & left_out))) continue;
    if (ring.at(i) < 0 || index.at(i) < 0 || !std::isfinite(x.at(i)) || !std::isfinite(y.at(i))) {
      throw util::InputError(fmt::format("spots: row {}: ring and index must be >= 0 and x_mm, y_mm finite", i));
    }
    out.push_back({{static_cast<int>(ring.at(i)), static_cast<int>(index.at(i))}, {x.at(i), y.at(i)}});
  }
  return out;
}

py::dict GridDict(const model::GridMap& g) {
  py::array_t<double> values({static_cast<py::ssize_t>(g.ny), static_cast<py::ssize_t>(g.nx)});
  std::copy(g.values.begin(), g.values.end(), values.mutable_data());
  py::array_t<double> x(g.nx), y(g.ny);
  for (int i = 0; i < g.nx; ++i) x.mutable_at(i) = g.x_min_mm + i * (g.x_max_mm - g.x_min_mm) / (g.nx - 1);
  for (int j = 0; j < g.ny; ++j) y.mutable_at(j) = g.y_min_mm + j * (g.y_max_mm - g.y_min_mm) / (g.ny - 1);
  return py::dict(py::arg("values") = values, py::arg("x_mm") = x, py::arg("y_mm") = y, py::arg("unit") = g.unit,
                  py::arg("title") = g.title);
}

// The maps the CLI's --maps writes as CSV (pipeline::AnalysisGridsOf), and the exact polar power maps.
py::dict MapsDict(const pipeline::AnalysisGrids& grids, const topo::PowerMaps& pm) {
  py::dict maps;
  maps["axial_power"] = GridDict(grids.axial_D);
  maps["tangential_power"] = GridDict(grids.tangential_D);
  if (grids.elevation_um) maps["elevation"] = GridDict(*grids.elevation_um);
  const auto polar = [&](const std::vector<double>& v) {
    py::array_t<double> out({static_cast<py::ssize_t>(pm.meridians), static_cast<py::ssize_t>(pm.radial_samples)});
    std::copy(v.begin(), v.end(), out.mutable_data());
    return out;
  };
  py::array_t<double> rho(pm.radial_samples), theta(pm.meridians);
  for (int k = 0; k < pm.radial_samples; ++k) rho.mutable_at(k) = pm.RhoMm(k);
  for (int j = 0; j < pm.meridians; ++j) theta.mutable_at(j) = pm.ThetaDeg(j);
  maps["polar"] = py::dict(py::arg("axial_D") = polar(pm.axial_D), py::arg("tangential_D") = polar(pm.tangential_D),
                           py::arg("rho_mm") = rho, py::arg("theta_deg") = theta);
  return maps;
}

// The result document and the maps of an analysis (with the U of its axial map when measured through a device);
// the maps are computed without the GIL.
py::dict MeasurementDict(const nlohmann::json& result, const topo::Analysis& a,
                         const std::vector<double>* axial_expanded_D = nullptr) {
  pipeline::AnalysisGrids grids;
  {
    py::gil_scoped_release release;
    grids = pipeline::AnalysisGridsOf(a);
  }
  py::dict maps = MapsDict(grids, a.power);
  if (axial_expanded_D) {
    py::array_t<double> u({static_cast<py::ssize_t>(a.power.meridians), static_cast<py::ssize_t>(a.power.radial_samples)});
    std::copy(axial_expanded_D->begin(), axial_expanded_D->end(), u.mutable_data());
    maps["polar"].cast<py::dict>()["axial_expanded_D"] = u;
  }
  return py::dict(py::arg("result") = ToPython(result), py::arg("maps") = maps);
}

py::dict ReconstructImage(const py::array& image, const model::DeviceFile& dev, const model::Config& cfg,
                          const std::string& estimator, bool truth, const pipeline::UncertaintyOptions& u_options) {
  const cv::Mat view = SensorImage(image, dev.device.camera);
  pipeline::EyeMeasurement m;
  try {
    py::gil_scoped_release release;
    m = pipeline::MeasureEye(view, dev.device, cfg, OptionsFor(estimator), truth ? &cfg.cornea : nullptr);
  } catch (const util::MeasurementRefused& e) {
    RaiseRefused(e.what(), {e.what()}, {{"valid", false}, {"refused", {e.what()}}});
  }
  nlohmann::json info;
  info["image"] = {{"indexed", m.spots.indexed},
                   {"unassigned", m.spots.unassigned},
                   {"missing", m.spots.missing},
                   {"undistort_failures", m.spots.undistort_failures}};
  info["capture"] = report::CaptureJson(m.spots.capture);
  info["valid"] = m.verdict.valid;
  if (!m.verdict.valid) {
    info["refused"] = m.verdict.reasons;
    RaiseRefused(fmt::format("measurement refused: {}", fmt::join(m.verdict.reasons, "; ")), m.verdict.reasons, info);
  }
  // Every number with its U, as `reconstruct --device` reports it (pipeline/measurement_uncertainty.h).
  const auto covariance = model::DeviceCovarianceOf(dev.calibration, "device");
  pipeline::MeasurementUncertainty u;
  try {
    py::gil_scoped_release release;
    u = pipeline::PropagateMeasurementUncertainty(m.spots.detected, dev.device, covariance, cfg, m.analysis, u_options);
  } catch (const std::runtime_error& e) {
    const std::string reason = fmt::format("its uncertainty cannot be evaluated: {}", e.what());
    info["valid"] = false;
    info["refused"] = {reason};
    RaiseRefused(fmt::format("measurement refused: {}", reason), {reason}, info);
  }
  info["uncertainty"] = report::MeasurementUncertaintyJson(u);
  if (const auto reason = pipeline::UncertaintyRefusal(u)) {
    info["valid"] = false;
    info["refused"] = {*reason};
    RaiseRefused(fmt::format("measurement refused: {}", *reason), {*reason}, info);
  }
  info.update(report::MeasurementJson(m.analysis, truth));
  report::WithdrawUndetermined(u, &info);
  return MeasurementDict(info, m.analysis, &u.axial_expanded_D);
}

py::dict Reconstruct(const py::object& config, const py::object& device, const py::object& image,
                     const py::object& spots, const std::string& estimator, bool truth, const std::string& eye_arg,
                     int uncertainty, unsigned seed) {
  if (uncertainty < 0) throw util::InputError("uncertainty: must be >= 0 (0: linear propagation)");
  if (!eye_arg.empty() && eye_arg != "OD" && eye_arg != "OS") throw util::InputError("eye: must be OD, OS or empty");
  const model::Config cfg = pipeline::ForEyes(ConfigArg(config));  // as `topocal reconstruct`
  const std::string& eye = eye_arg.empty() ? cfg.eye : eye_arg;  // the argument, else the configuration's
  if (image.is_none() == spots.is_none()) throw util::InputError("reconstruct: give one of image or spots");
  if (!image.is_none()) {
    if (device.is_none()) throw util::InputError("reconstruct: image needs device (the calibrated device)");
    pipeline::UncertaintyOptions u_options;
    u_options.device_draws = uncertainty;
    u_options.seed = seed;
    py::dict out = ReconstructImage(image.cast<py::array>(), DeviceArg(device), cfg, estimator, truth, u_options);
    if (!eye.empty()) out["result"]["eye"] = eye;
    return out;
  }
  const std::vector<model::PlaneSpot> measured = SpotsFrom(spots.cast<py::array>());
  std::optional<model::DeviceFile> dev;
  if (!device.is_none()) dev = DeviceArg(device);
  topo::Analysis a;
  {
    py::gil_scoped_release release;
    const model::BiconicParams* cornea = truth ? &cfg.cornea : nullptr;
    a = dev ? pipeline::AnalyzeThroughDevice(measured, dev->device, cfg, cornea)
            : topo::AnalyzeSpots(measured, model::DesignNullScreen(cfg.ideal_image, cfg.topographer).targets, cfg,
                                 cornea);
  }
  nlohmann::json info;
  if (!eye.empty()) info["eye"] = eye;
  info["spots_read"] = measured.size();
  info.update(report::MeasurementJson(a, truth));
  return MeasurementDict(info, a);
}

}  // namespace

void RegisterMeasure(py::module_& m) {
  PYBIND11_NUMPY_DTYPE(SpotRow, ring, index, x_mm, y_mm, u_px, v_px, flags);
  py::dict flags;
  for (const auto& [name, bit] : {std::pair{"near_blob", correct::kNearBlob}, {"saturated", correct::kSaturated},
                                  {"truncated", correct::kTruncated}, {"flux_outlier", correct::kFluxOutlier},
                                  {"uneven_background", correct::kUnevenBackground},
                                  {"surface_outlier", correct::kSurfaceOutlier},
                                  {"surface_labelled", correct::kSurfaceLabelled}}) {
    flags[name] = static_cast<unsigned>(bit);
  }
  m.attr("SPOT_FLAGS") = flags;
  m.attr("SPOT_DTYPE") = py::dtype::of<SpotRow>();
  m.def("detect", &Detect, py::arg("image"), py::arg("device"), py::arg("config"), py::arg("estimator") = "psf",
        py::arg("return_summary") = false,
        "Detect, identify and flag the spots of a raw sensor image (2-D uint8/uint16 array) through a device, as "
        "`topocal detect` (every identity checked against the surface the others give). Returns a structured "
        "array of SPOT_DTYPE (ring, index, x_mm, y_mm on the detection plane as recorded, u_px, v_px, flags: "
        "SPOT_FLAGS bits; ring 0: a blob without identity), and with "
        "return_summary=True also the summary dict of `detect --json`. Raises MeasurementRefused when the "
        "pattern cannot be identified or the identities are refused.");
  m.def("_reconstruct", &Reconstruct, py::arg("config"), py::arg("device") = py::none(),
        py::arg("image") = py::none(), py::arg("spots") = py::none(), py::arg("estimator") = "psf",
        py::arg("truth") = false, py::arg("eye") = "", py::arg("uncertainty") = 0, py::arg("seed") = 1u,
        "See topocal.reconstruct.");
}

}  // namespace topocal::python

// topocal.calibrate and topocal.calibrate_device: the camera from target views (images or corner arrays), the
// whole device from reference-ball images — the library calls of `topocal calibrate` and `topocal device calibrate`.
#include <fmt/format.h>

#include <optional>

#include "calib/calibrate.h"
#include "calib/calibration_file.h"
#include "calib/camera_exchange.h"
#include "calib/detect.h"
#include "calib/target.h"
#include "imageio/image_file.h"
#include "pipeline/device_calibration.h"
#include "python/src/py_common.h"
#include "util/io.h"
#include "util/version.h"

namespace topocal::python {
namespace {

// One view given as a corner table: (target_mm (N, 2) or (N, 3) on the target plane, image_px (N, 2)).
calib::ViewObservations ViewFromCorners(const py::handle& view, int index, int width_px, int height_px) {
  const auto what = fmt::format("corners[{}]", index);
  const auto pair = py::reinterpret_borrow<py::sequence>(view);
  if (py::len(pair) != 2) throw util::InputError(fmt::format("{}: need (target_mm, image_px)", what));
  const auto target = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(pair[0]);
  const std::vector<Eigen::Vector2d> image = PointsFrom(pair[1].cast<py::array>(), what + ".image_px");
  if (!target || target.ndim() != 2 || (target.shape(1) != 2 && target.shape(1) != 3) ||
      target.shape(0) != static_cast<py::ssize_t>(image.size())) {
    throw util::InputError(fmt::format("{}: target_mm must be (N, 2) or (N, 3) with the N rows of image_px", what));
  }
  calib::ViewObservations v;
  v.image_path = what;
  v.image_width = width_px;
  v.image_height = height_px;
  for (size_t i = 0; i < image.size(); ++i) {
    const auto r = static_cast<py::ssize_t>(i);
    const Eigen::Vector3d t(target.at(r, 0), target.at(r, 1), target.shape(1) == 3 ? target.at(r, 2) : 0.0);
    if (!t.allFinite()) throw util::InputError(fmt::format("{}: target_mm row {} is not finite", what, i));
    v.corners.push_back({static_cast<int>(i), image[i], t});
  }
  return v;
}

// Detects the target in each image (array or path); views without the target are reported in `skipped`.
std::vector<calib::ViewObservations> ViewsFromImages(const calib::TargetDescription& target, const py::list& images,
                                                     std::vector<std::string>* names, py::list* skipped) {
  std::vector<calib::ViewObservations> views;
  for (size_t i = 0; i < images.size(); ++i) {
    const py::object image = images[i];
    calib::DetectionResult d;
    std::string name;
    if (py::isinstance<py::array>(image)) {
      name = fmt::format("images[{}]", i);
      const cv::Mat view = ImageView(image.cast<py::array>(), name);
      py::gil_scoped_release release;
      d = calib::DetectTargetDetailed(target, view);
    } else {
      name = PathArg(image, fmt::format("images[{}]", i));
      py::gil_scoped_release release;
      auto found = calib::DetectTargetInFile(target, name);
      d.view = std::move(found);
      d.message = d.view ? "" : "no target found";
    }
    if (!d.view) {
      skipped->append(py::make_tuple(name, d.message.empty() ? std::string("no target found") : d.message));
      continue;
    }
    d.view->image_path = name;
    names->push_back(name);
    views.push_back(std::move(*d.view));
  }
  return views;
}

py::dict Calibrate(const py::object& target_path, const py::object& images, const py::object& corners,
                   const py::object& image_size, const std::string& model, const std::vector<std::string>& fix,
                   double fix_aspect, bool board_warp) {
  const auto kind = calib::ParseDistortionModel(model);
  if (!kind) throw util::InputError(fmt::format("model: '{}' is not one of {}", model, calib::DistortionModelNames()));
  calib::CalibrationOptions options;
  options.model = *kind;
  options.fixed = {fix.begin(), fix.end()};
  options.fixed_aspect_ratio = fix_aspect;
  options.fit_board_warp = board_warp;
  std::string why;
  if (!options.IsValid(&why)) throw util::InputError(why);
  if (images.is_none() == corners.is_none()) throw util::InputError("calibrate: give one of images or corners");
  const std::string target_file = PathArg(target_path, "target");
  const auto target = calib::LoadTargetDescription(target_file);
  std::vector<calib::ViewObservations> views;
  std::vector<std::string> names;
  py::list skipped;
  if (!images.is_none()) {
    views = ViewsFromImages(target, images.cast<py::list>(), &names, &skipped);
  } else {
    if (image_size.is_none()) throw util::InputError("calibrate: corners need image_size = (width_px, height_px)");
    const auto [w, h] = image_size.cast<std::pair<int, int>>();
    if (w <= 0 || h <= 0) throw util::InputError("image_size: width and height must be > 0");
    const auto list = corners.cast<py::list>();
    for (size_t i = 0; i < list.size(); ++i) {
      views.push_back(ViewFromCorners(list[i], static_cast<int>(i), w, h));
      names.push_back(views.back().image_path);
    }
  }
  calib::CalibrationResult result;
  {
    py::gil_scoped_release release;
    result = calib::CalibrateMultiView(views, options);
  }
  for (const auto& s : result.skipped_views) skipped.append(py::make_tuple(names[static_cast<size_t>(s.view)], s.reason));
  if (!result.ok()) {
    throw std::runtime_error(fmt::format("calibration failed ({}): {}", calib::ToString(result.status), result.message));
  }
  const calib::CalibrationProvenance provenance{target_file, names, {}};
  return py::dict(py::arg("report") = ToPython(nlohmann::json::parse(calib::CalibrationReportJson(result, provenance))),
                  py::arg("yaml") = calib::CalibrationFileText(result, provenance), py::arg("skipped") = skipped);
}

model::DeviceFile CalibrateDevice(const py::object& config, const py::object& nominal, const py::list& balls,
                                  const std::vector<double>& radii_mm, int datum, double spot_sigma_px,
                                  bool fit_distortion, bool accept_inadequate) {
  const model::Config cfg = ConfigArg(config);
  const model::DeviceFile start = DeviceArg(nominal);
  if (balls.empty()) throw util::InputError("balls: at least one reference-ball image is needed");
  if (radii_mm.size() != balls.size()) {
    throw util::InputError(fmt::format("radii_mm: {} radii for {} ball images", radii_mm.size(), balls.size()));
  }
  if (datum < 1 || datum > static_cast<int>(balls.size())) {
    throw util::InputError(fmt::format("datum: must name one of the {} balls (1..{})", balls.size(), balls.size()));
  }
  calib::DeviceFitOptions options;
  options.datum_ball = datum - 1;
  options.spot_sigma_px = spot_sigma_px;
  options.fit_distortion = fit_distortion;
  std::string why;
  if (!options.IsValid(&why)) throw util::InputError(why);
  std::vector<pipeline::BallImage> images;
  const auto& camera = start.device.camera;
  for (size_t i = 0; i < balls.size(); ++i) {
    const auto name = fmt::format("balls[{}]", i);
    const cv::Mat view = ImageView(balls[i].cast<py::array>(), name);
    imageio::RequireSize(view, name, camera.width_px, camera.height_px, "the nominal device");
    images.push_back({name, view, radii_mm[i]});
  }
  pipeline::DeviceCalibration result;
  {
    py::gil_scoped_release release;
    result = pipeline::CalibrateDevice(images, start.device, cfg, options);
  }
  const auto& fit = result.fit;
  if (!fit.ok) throw std::runtime_error(fmt::format("device calibration failed: {}", fit.message));
  if (!fit.model_adequate && !accept_inadequate) {
    throw std::runtime_error(fmt::format("device calibration: chi2/dof = {:.3g} > {}: the device model does not "
                                         "describe these images (accept_inadequate=True returns it flagged)",
                                         fit.chi2_per_dof, options.max_chi2_per_dof));
  }
  nlohmann::json report = pipeline::DeviceCalibrationJson(result);
  report["tool"] = fmt::format("topocal {}", kVersion);
  report["spot_sigma_px"] = options.spot_sigma_px;
  return {fit.device, report};
}

std::string ExportText(const py::object& calibration, const std::string& to, const std::string& camera_name) {
  const auto format = calib::ParseExportFormat(to);
  if (!format) throw util::InputError(fmt::format("to: '{}' is not ros, kalibr, mrcal or opencv", to));
  const std::string path = PathArg(calibration, "calibration");
  calib::ExportOptions options;
  options.camera_name = camera_name;
  return calib::ExportCalibration(calib::LoadCalibrationFile(path), *format, path, options);
}

}  // namespace

void RegisterCalibration(py::module_& m) {
  m.def(
      "import_calibration",
      [](const py::object& path, const std::string& from, const std::string& camera) {
        return calib::ImportCalibrationText(from, PathArg(path, "path"), camera);
      },
      py::arg("path"), py::arg("from_format"), py::arg("camera") = "cam0",
      "Another tool's calibration (from_format: kalibr, opencv, mrcal or ros; camera: the camchain key for kalibr) "
      "as the text of a calibration file every --calibration reads, as `topocal import` writes it.");
  m.def(
      "_write_file",
      [](const py::object& path, const std::string& text) { util::WriteFileAtomic(PathArg(path, "path"), text); },
      py::arg("path"), py::arg("text"), "Write a file as every topocal output is written (util::WriteFileAtomic).");
  m.def("export_calibration", &ExportText, py::arg("calibration"), py::arg("to_format"),
        py::arg("camera_name") = "topocal",
        "A calibration file (topocal or OpenCV YAML) as another tool's file text (to_format: ros, kalibr, mrcal or "
        "opencv), as `topocal export` writes it.");
  m.def("_calibrate", &Calibrate, py::arg("target"), py::arg("images") = py::none(), py::arg("corners") = py::none(),
        py::arg("image_size") = py::none(), py::arg("model") = "brown5", py::arg("fix") = std::vector<std::string>{},
        py::arg("fix_aspect") = 0.0, py::arg("board_warp") = false, "See topocal.calibrate.");
  m.def("calibrate_device", &CalibrateDevice, py::arg("config"), py::arg("nominal"), py::arg("balls"),
        py::arg("radii_mm"), py::arg("datum") = 1, py::arg("spot_sigma_px") = 0.04, py::arg("fit_distortion") = true,
        py::arg("accept_inadequate") = false,
        "Calibrate the whole device (screen pose, principal point, a, distortion) from raw reference-ball images "
        "(2-D uint8/uint16 arrays) of certified radii_mm, as `topocal device calibrate`. Returns the calibrated "
        "Device; its `calibration` holds every parameter with its standard deviation. Raises Error when the fit "
        "fails or (unless accept_inadequate) its chi^2/dof says the model does not describe the images.");
}

}  // namespace topocal::python

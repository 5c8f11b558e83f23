// topocal.Config and topocal.Device: the configuration (the null-screen design, the cornea, the reconstruction's
// settings) and the device (camera, distortion, screen pose), read and written in the CLI's JSON formats.
#include <fmt/format.h>

#include <cmath>
#include <limits>

#include "model/opencv_view.h"
#include "model/distortion.h"
#include "python/src/py_common.h"
#include "util/io.h"

namespace topocal::python {
namespace {

py::tuple OpenCvViewTuple(const model::DeviceFile& f) {
  const model::CameraModel k = model::OpenCvView(f.device);
  py::array_t<double> matrix({3, 3});
  auto m = matrix.mutable_unchecked<2>();
  const double values[3][3] = {{k.fx_px, 0, k.cx_px}, {0, k.fy_px, k.cy_px}, {0, 0, 1}};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m(r, c) = values[r][c];
  }
  const int n = model::LensParameterCount(k.lens);
  py::array_t<double> dist(n);
  for (int i = 0; i < n; ++i) dist.mutable_at(i) = k.dist[static_cast<size_t>(i)];
  return py::make_tuple(matrix, dist);
}

py::array_t<double> PixelOf(const model::DeviceFile& f, const py::array& points_mm) {
  std::vector<Eigen::Vector2d> points = PointsFrom(points_mm, "points_mm");
  for (auto& p : points) p = f.device.PixelOf(p);
  return PointsArray(points);
}

py::array_t<double> UndistortedOf(const model::DeviceFile& f, const py::array& points_px) {
  std::vector<Eigen::Vector2d> points = PointsFrom(points_px, "points_px");
  for (auto& p : points) {
    const auto u = f.device.UndistortedOf(p);
    p = u ? *u : Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  return PointsArray(points);
}

py::array_t<double> DistortedOf(const model::DeviceFile& f, const py::array& points_px) {
  std::vector<Eigen::Vector2d> points = PointsFrom(points_px, "points_px");
  for (auto& p : points) p = f.device.DistortedOf(p);
  return PointsArray(points);
}

void RegisterConfig(py::module_& m) {
  py::class_<model::Config>(m, "Config", "A topographer configuration (docs/configuration.md): the null-screen "
                                         "design, the cornea it simulates, the reconstruction's settings.")
      .def_static(
          "load", [](const py::object& path) { return model::LoadConfig(PathArg(path, "path")); }, py::arg("path"),
                  "Read and validate a configuration JSON file. Raises InputError naming the file and key.")
      .def_static(
          "from_json", [](const std::string& text) { return model::ParseConfig(text, "<json>"); }, py::arg("text"),
          "Parse and validate configuration JSON text.")
      .def("to_json", &model::ConfigToJson, "The configuration as JSON text (the schema `load` reads).")
      .def("to_dict", [](const model::Config& c) { return ToPython(nlohmann::json::parse(model::ConfigToJson(c))); },
           "The configuration as a dict (the JSON file's keys).")
      .def_property_readonly("path", [](const model::Config& c) { return c.path; }, "The file it was read from.")
      .def("__repr__", [](const model::Config& c) {
        return fmt::format("<topocal.Config {}>", c.path.empty() ? std::string("(from JSON)") : c.path);
      });
}

void RegisterDevice(py::module_& m) {
  py::class_<model::DeviceFile>(m, "Device", "A topographer as built (docs/device.md): its camera (pixel pitch, "
                                             "sensor, principal point, pinhole-to-detection-plane a), its lens "
                                             "distortion on the detection plane and the pose of the null screen; "
                                             "with the calibration that produced it, when it was calibrated.")
      .def_static(
          "load", [](const py::object& path) { return model::LoadDevice(PathArg(path, "path")); }, py::arg("path"),
                  "Read and validate a device JSON file (as `topocal device calibrate` writes it).")
      .def_static(
          "from_json", [](const std::string& text) { return model::ParseDevice(text, "<json>"); }, py::arg("text"),
          "Parse and validate device JSON text.")
      .def("to_json", [](const model::DeviceFile& f) { return model::DeviceToJson(f.device, f.calibration); },
           "The device file's JSON text, calibration included.")
      .def("to_dict",
           [](const model::DeviceFile& f) {
             return ToPython(nlohmann::json::parse(model::DeviceToJson(f.device, f.calibration)));
           },
           "The device file as a dict.")
      .def(
          "save",
          [](const model::DeviceFile& f, const py::object& path) {
            util::WriteFileAtomic(PathArg(path, "path"), model::DeviceToJson(f.device, f.calibration));
          },
          py::arg("path"), "Write the device file atomically (a temporary file renamed into place).")
      .def_property_readonly("width_px", [](const model::DeviceFile& f) { return f.device.camera.width_px; })
      .def_property_readonly("height_px", [](const model::DeviceFile& f) { return f.device.camera.height_px; })
      .def_property_readonly("pixel_pitch_um", [](const model::DeviceFile& f) { return f.device.camera.pixel_pitch_um; })
      .def_property_readonly("pixel_aspect", [](const model::DeviceFile& f) { return f.device.camera.pixel_aspect; },
                             "Pitch along v / pitch along u: OpenCV's fx / fy (1 for square pixels).")
      .def_property_readonly("a_mm", [](const model::DeviceFile& f) { return f.device.camera.a_mm; },
                             "Pinhole to detection plane, mm (the paper's a), as built.")
      .def_property_readonly(
          "principal_point_px",
          [](const model::DeviceFile& f) {
            return py::make_tuple(f.device.camera.principal_point_px.x(), f.device.camera.principal_point_px.y());
          },
          "(u, v) where the optical axis meets the sensor, px.")
      .def_property_readonly(
          "calibration",
          [](const model::DeviceFile& f) { return f.calibration.is_null() ? py::none() : ToPython(f.calibration); },
          "The calibration section (parameters with standard deviations, chi^2/dof, balls), or None for a "
          "hand-written device.")
      .def("pixel_of", &PixelOf, py::arg("points_mm"),
           "Undistorted detection-plane points (N, 2) mm -> pixels (N, 2): the distortion, then the camera.")
      .def("undistorted_of", &UndistortedOf, py::arg("points_px"),
           "Pixels (N, 2) -> undistorted detection-plane points (N, 2) mm; NaN rows outside the distortion's "
           "invertible domain.")
      .def("distorted_of", &DistortedOf, py::arg("points_px"),
           "Pixels (N, 2) -> detection-plane points (N, 2) mm as recorded (distorted).")
      .def("opencv_view", &OpenCvViewTuple,
           "(camera_matrix 3x3, dist_coeffs [k1, k2, p1, p2, k3]) of the OpenCV camera that maps the same rays to "
           "the same pixels: cv2.projectPoints of (M (x_mm - c_mm) / f_mm, 1) gives pixel_of(x_mm).")
      .def("__repr__", [](const model::DeviceFile& f) {
        return fmt::format("<topocal.Device {} x {} px, {} um, a = {} mm{}>", f.device.camera.width_px,
                           f.device.camera.height_px, f.device.camera.pixel_pitch_um, f.device.camera.a_mm,
                           f.calibration.is_null() ? "" : ", calibrated");
      });
}

}  // namespace

void RegisterModel(py::module_& m) {
  RegisterConfig(m);
  RegisterDevice(m);
}

}  // namespace topocal::python

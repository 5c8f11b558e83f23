// topocal._topocal: the compiled part of the Python package `topocal` (python/topocal/__init__.py re-exports it).
#include <fmt/format.h>

#include <glog/logging.h>
#include <opencv2/core/utility.hpp>

#include <stdexcept>

#include "python/src/py_common.h"
#include "util/io.h"
#include "util/build_info.h"
#include "util/version.h"

namespace topocal::python {
namespace {

// The exception types, created once when the module is imported and alive as long as the interpreter.
PyObject* g_error = nullptr;        // topocal.Error(RuntimeError): a computation failed
PyObject* g_input_error = nullptr;  // topocal.InputError(ValueError): bad input, named
PyObject* g_refused = nullptr;      // topocal.MeasurementRefused(topocal.Error): the data cannot support it

PyObject* NewException(const char* name, const char* doc, PyObject* base) {
  PyObject* type = PyErr_NewExceptionWithDoc(name, doc, base, nullptr);
  if (type == nullptr) throw py::error_already_set();
  return type;
}

}  // namespace

py::object ToPython(const nlohmann::json& j) {
  // Held for the interpreter's life and never released: a static py::object would be destroyed after the
  // interpreter has finalised.
  static const py::handle loads = py::object(py::module_::import("json").attr("loads")).release();
  return loads(j.dump());
}

cv::Mat ImageView(const py::array& image, const std::string& what) {
  const bool u8 = py::isinstance<py::array_t<std::uint8_t>>(image);
  const bool u16 = py::isinstance<py::array_t<std::uint16_t>>(image);
  if (image.ndim() != 2 || !(u8 || u16)) {
    throw util::InputError(fmt::format("{}: need a 2-D uint8 or uint16 array (a grey image), got {} dimensions of {}",
                                       what, image.ndim(), py::str(image.dtype()).cast<std::string>()));
  }
  if (!(image.flags() & py::array::c_style)) {
    throw util::InputError(fmt::format("{}: the array is not C-contiguous (pass numpy.ascontiguousarray(image))", what));
  }
  // cv::Mat over the array's own memory: no copy; the caller keeps the array alive for the call.
  return cv::Mat(static_cast<int>(image.shape(0)), static_cast<int>(image.shape(1)), u8 ? CV_8UC1 : CV_16UC1,
                 const_cast<void*>(image.data()));
}

std::vector<Eigen::Vector2d> PointsFrom(const py::array& points, const std::string& what) {
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(points);
  if (!a || a.ndim() != 2 || a.shape(1) != 2) {
    throw util::InputError(fmt::format("{}: need an (N, 2) array of numbers", what));
  }
  std::vector<Eigen::Vector2d> out(static_cast<size_t>(a.shape(0)));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    out[i] = {a.at(i, 0), a.at(i, 1)};
    if (!out[i].allFinite()) throw util::InputError(fmt::format("{}: row {} is not finite", what, i));
  }
  return out;
}

py::array_t<double> PointsArray(const std::vector<Eigen::Vector2d>& points) {
  py::array_t<double> out({static_cast<py::ssize_t>(points.size()), py::ssize_t{2}});
  auto v = out.mutable_unchecked<2>();
  for (size_t i = 0; i < points.size(); ++i) {
    v(i, 0) = points[i].x();
    v(i, 1) = points[i].y();
  }
  return out;
}

std::string PathArg(const py::object& path, const std::string& what) {
  if (py::isinstance<py::str>(path)) return path.cast<std::string>();
  if (py::hasattr(path, "__fspath__")) return path.attr("__fspath__")().cast<std::string>();
  throw util::InputError(fmt::format("{}: need a path (str or os.PathLike)", what));
}

model::Config ConfigArg(const py::object& config) {
  if (py::isinstance<model::Config>(config)) return config.cast<model::Config>();
  return model::LoadConfig(PathArg(config, "config"));
}

model::DeviceFile DeviceArg(const py::object& device) {
  if (py::isinstance<model::DeviceFile>(device)) return device.cast<model::DeviceFile>();
  return model::LoadDevice(PathArg(device, "device"));
}

void RaiseRefused(const std::string& message, const std::vector<std::string>& reasons, const nlohmann::json& result) {
  py::object exc = py::reinterpret_borrow<py::object>(g_refused)(message);
  exc.attr("reasons") = py::cast(reasons);
  exc.attr("result") = ToPython(result);
  PyErr_SetObject(g_refused, exc.ptr());
  throw py::error_already_set();
}

void RegisterErrors(py::module_& m) {
  g_error = NewException("topocal.Error", "A computation failed (a fit did not converge, no usable views).",
                         PyExc_RuntimeError);
  g_input_error = NewException("topocal.InputError",
                               "Bad input: a missing or malformed file, key or argument; the message names it.",
                               PyExc_ValueError);
  g_refused = NewException("topocal.MeasurementRefused",
                           "The capture cannot support the measurement: `reasons` says why, `result` is the JSON "
                           "the CLI writes (marked valid = False, no clinical number).",
                           g_error);
  m.attr("Error") = py::handle(g_error);
  m.attr("InputError") = py::handle(g_input_error);
  m.attr("MeasurementRefused") = py::handle(g_refused);
  // The library's error classes (docs/errors.md) as Python's; the most derived first.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const util::InputError& e) {
      PyErr_SetString(g_input_error, e.what());
    } catch (const util::MeasurementRefused& e) {
      PyErr_SetString(g_refused, e.what());
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(g_input_error, e.what());
    } catch (const std::runtime_error& e) {
      PyErr_SetString(g_error, e.what());
    }
  });
}

}  // namespace topocal::python

PYBIND11_MODULE(_topocal, m) {
  using namespace topocal::python;
  m.doc() = "topocal: calibrate, correct and verify cone (null-screen) corneal topographers (docs/python.md).";
  m.attr("__version__") = topocal::kVersion;
  m.attr("__commit__") = topocal::BuildCommit();  // the git commit it was built from (util/build_info.h)
  // Ceres logs through glog (failed steps, rank-deficient covariances); every failure reaches Python as an exception
  // or a result field, and the module prints nothing (as the CLI's tools/cli_app.cc).
  FLAGS_minloglevel = google::GLOG_FATAL;
  m.def(
      "set_num_threads", [](int n) { cv::setNumThreads(n); }, py::arg("n"),
      "Threads OpenCV may use inside detection and image work (0: one, as OpenCV's setNumThreads; negative: "
      "OpenCV's default). The results do not depend on it.");
  m.def("get_num_threads", [] { return cv::getNumThreads(); }, "OpenCV's thread count (set_num_threads).");
  RegisterErrors(m);
  RegisterModel(m);
  RegisterMeasure(m);
  RegisterCalibration(m);
  RegisterRecords(m);
}

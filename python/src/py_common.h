#pragma once
// What every part of the Python module (python/src/*.cc) shares: the conversions between Python and topocal's
// types, and the errors raised into Python.
//
// Conventions (docs/python.md): lengths in mm, angles in degrees, powers in diopters, pixels only for image
// positions (OpenCV's convention: the centre of the top-left pixel is (0, 0)). Point sets are (N, 2) float64 arrays.
// Images are 2-D uint8 or uint16 arrays, read in place (no copy). Results that the CLI writes as JSON come back as
// the same dicts (decoded from the same JSON text, so the doubles are the CLI's to the last bit).
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core/mat.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "model/config.h"
#include "model/device.h"

namespace topocal::python {

namespace py = pybind11;

// JSON -> Python through the json module: the same text the CLI writes, decoded by Python.
py::object ToPython(const nlohmann::json& j);

// A 2-D C-contiguous uint8 or uint16 array as a cv::Mat sharing its memory. topocal.InputError naming `what`
// for any other array.
cv::Mat ImageView(const py::array& image, const std::string& what);

// An (N, 2) array of numbers as points; topocal.InputError naming `what` otherwise.
std::vector<Eigen::Vector2d> PointsFrom(const py::array& points, const std::string& what);
// Points as an (N, 2) float64 array.
py::array_t<double> PointsArray(const std::vector<Eigen::Vector2d>& points);

// A configuration or device given as an object or as a path (str or os.PathLike) to its JSON file.
model::Config ConfigArg(const py::object& config);
model::DeviceFile DeviceArg(const py::object& device);
// str(path) for str and os.PathLike.
std::string PathArg(const py::object& path, const std::string& what);

// Raises topocal.MeasurementRefused with `reasons` (list of str) and `result` (dict: the JSON the CLI writes for a
// refused measurement) as attributes.
[[noreturn]] void RaiseRefused(const std::string& message, const std::vector<std::string>& reasons,
                               const nlohmann::json& result);

// The module's parts.
void RegisterErrors(py::module_& m);
void RegisterModel(py::module_& m);
void RegisterMeasure(py::module_& m);
void RegisterCalibration(py::module_& m);
void RegisterRecords(py::module_& m);

}  // namespace topocal::python

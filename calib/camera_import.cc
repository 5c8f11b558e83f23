// The readers of other tools' calibrations (calib/camera_exchange.h): Kalibr camchain and ROS camera_info YAML
// through the one FileStorage door (calib/file_storage.h), mrcal's .cameramodel through a small reader of the
// Python literal it is. The writers are in calib/camera_exchange.cc.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <set>
#include <tuple>
#include <string>
#include <utility>
#include <vector>

#include "calib/camera_exchange.h"
#include "calib/file_storage.h"
#include "calib/yaml_section.h"
#include "util/io.h"

namespace topocal::calib {
namespace {

[[noreturn]] void Bad(const std::string& path, const std::string& key, const std::string& problem) {
  throw util::InputError(fmt::format("{}: {}: {}", path, key, problem));
}

// A token quoted for a message: at most `max` characters, anything not printable ASCII as \xNN (one line).
std::string Shown(const std::string& token, size_t max = 100) {
  std::string out;
  for (const char ch : token.substr(0, max)) {
    const auto u = static_cast<unsigned char>(ch);
    out += u >= 0x20 && u < 0x7f ? std::string(1, ch) : fmt::format("\\x{:02x}", u);
  }
  return token.size() > max ? out + "..." : out;
}

// ---- YAML (Kalibr, ROS) ------------------------------------------------------------------------------------------

// PyYAML (which writes Kalibr's camchains, and ROS camera_info files from Python) puts a block sequence at the
// indentation of its key:
//   T_cn_cnm1:
//   - [1.0, 0.0, 0.0, 0.1]
// YAML allows it; cv::FileStorage's parser does not. Such a sequence (its items and their continuation lines) is
// indented by two more spaces, which means the same to YAML and reads in cv::FileStorage.
std::string IndentCompactSequences(const std::string& text) {
  std::vector<std::string> lines;
  for (size_t start = 0; start <= text.size();) {
    const size_t end = text.find('\n', start);
    lines.push_back(text.substr(start, end == std::string::npos ? std::string::npos : end - start));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  const auto indent = [](const std::string& l) { return l.find_first_not_of(' '); };
  const auto is_item = [&](const std::string& l) {
    const size_t i = indent(l);
    return i != std::string::npos && l[i] == '-' && (i + 1 == l.size() || l[i + 1] == ' ');
  };
  std::string out;
  for (size_t i = 0; i < lines.size(); ++i) {
    out += lines[i] + (i + 1 < lines.size() ? "\n" : "");
    const size_t key_indent = indent(lines[i]);
    const auto trimmed_end = lines[i].find_last_not_of(" \t\r");
    if (key_indent == std::string::npos || is_item(lines[i]) || trimmed_end == std::string::npos ||
        lines[i][trimmed_end] != ':' || i + 1 >= lines.size() || !is_item(lines[i + 1]) ||
        indent(lines[i + 1]) != key_indent) {
      continue;
    }
    // The sequence: items at the key's indentation and anything indented deeper, up to the next line at or left of
    // the key that is not an item.
    size_t j = i + 1;
    for (; j < lines.size(); ++j) {
      const size_t n = indent(lines[j]);
      if (n == std::string::npos) continue;  // blank
      if (n < key_indent || (n == key_indent && !is_item(lines[j]))) break;
      lines[j] = "  " + lines[j];
    }
  }
  return out;
}

// Another tool's YAML file, opened the one way topocal reads YAML (OpenFileStorage: size, nesting, duplicate keys
// checked). cv::FileStorage reads YAML only after a "%YAML" directive, which Kalibr, ROS and PyYAML do not write.
cv::FileStorage OpenToolYaml(const std::string& path) {
  std::string text = util::ReadFile(path);
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) Bad(path, "file", "empty");
  if (text.compare(first, 5, "%YAML") != 0) text = "%YAML:1.0\n---\n" + text;
  return OpenFileStorage(IndentCompactSequences(text), path);
}

// Values no camera has, whatever format they came in: a focal length <= 0 or a principal point outside the image
// (OpenCV's pixel convention: the image spans -0.5 ... width - 0.5). Finite values and a size >= 1 are checked by
// the readers.
void RequirePhysicalCamera(const model::CameraModel& c, const std::string& path, const std::string& key) {
  if (!(c.fx_px > 0 && c.fy_px > 0))
    Bad(path, key, fmt::format("focal lengths fx = {}, fy = {} must be > 0", c.fx_px, c.fy_px));
  if (!(c.cx_px >= -0.5 && c.cx_px <= c.width_px - 0.5 && c.cy_px >= -0.5 && c.cy_px <= c.height_px - 0.5)) {
    Bad(path, key,
        fmt::format("principal point ({}, {}) px lies outside the {} x {} image", c.cx_px, c.cy_px, c.width_px,
                    c.height_px));
  }
}

// ---- ROS camera_info ---------------------------------------------------------------------------------------------

// A camera_info matrix {rows, cols, data}: rows x cols as expected, data of rows * cols finite numbers.
std::vector<double> ReadRosMatrix(YamlSection& root, const std::string& key, int rows, int cols) {
  const cv::FileNode node = root.Node(key);
  if (!node.isMap()) root.Fail(key, "not a mapping {rows, cols, data}");
  YamlSection matrix(node, root.Origin(), key + ".");
  const int r = matrix.Int("rows"), c = matrix.Int("cols");
  if (r != rows || c != cols) root.Fail(key, fmt::format("expected {} x {}, found rows {}, cols {}", rows, cols, r, c));
  return matrix.Numbers("data", static_cast<size_t>(rows * cols));
}

// The distortion models of ROS (sensor_msgs/distortion_models.h) that are OpenCV's: plumb_bob (k1 k2 t1 t2 k3) and
// rational_polynomial (k1 k2 t1 t2 k3 k4 k5 k6). The coefficients, and the smallest lens model that holds them.
std::pair<model::LensModelId, model::LensCoefficients> ReadRosDistortion(YamlSection& root) {
  const std::string model_name = root.String("distortion_model");
  const auto named = model::LensModelFromName(model_name, model::LensNaming::kRos);
  if (!named) {
    root.Fail("distortion_model",
              fmt::format("'{}': topocal's lens models are OpenCV's: {} (equidistant is a fisheye model topocal does "
                          "not fit)",
                          Shown(model_name), model::LensModelNames(" or ", model::LensNaming::kRos)));
  }
  const int n = model::LensParameterCount(*named);
  const std::string key = "distortion_coefficients";
  const cv::FileNode node = root.Has(key) ? root.Node(key) : cv::FileNode();
  if (!node.empty() && node.isMap() && !node["data"].empty() && node["data"].isSeq() &&
      node["data"].size() != static_cast<size_t>(n)) {
    root.Fail(key + ".data", fmt::format("{} has {} coefficients, found {}", model_name, n, node["data"].size()));
  }
  const std::vector<double> d = ReadRosMatrix(root, key, 1, n);
  model::LensCoefficients k{};
  std::copy(d.begin(), d.end(), k.begin());
  return {model::SmallestLensModelFor(k), k};
}

// ---- mrcal .cameramodel: a Python literal --------------------------------------------------------------------------
//
// mrcal writes a .cameramodel as a Python dict literal and reads it with ast.literal_eval: '#' comments, single or
// double quotes, trailing commas, tuples, and the optimization_inputs blob as a bytes literal b'...'. YAML and JSON
// readers refuse single quotes, b'' and trailing commas, and no C++ library Debian packages parses Python literals,
// so this reads exactly that grammar by hand: dict (string keys), list, tuple, str/bytes (r b u prefixes,
// triple quotes), int/float, None, True, False. Anything else literal_eval would also refuse (names such as nan or
// inf, expressions) is refused, and so are a top-level key given twice and nesting deeper than 64 levels. Only the
// values of the keys topocal reads are kept; the others (optimization_inputs, valid_intrinsics_region, ...) are
// checked for syntax and dropped, so that memory stays of the order of the file.

inline constexpr size_t kMaxCameraModelBytes = 64u << 20;  // optimization_inputs of a large solve: a few MB
inline constexpr int kMaxLiteralDepth = 64;
inline constexpr size_t kMaxKeptValues = 100000;  // in the keys read: a splined model has a few thousand

struct PyValue {
  enum class Kind { kNumber, kString, kSequence, kDict, kConstant } kind = Kind::kConstant;
  double number = 0;
  bool integral = false;          // kNumber written as an integer (no '.', no exponent)
  std::string text;               // kString: the contents; kConstant: None, True or False
  std::vector<PyValue> items;     // kSequence: the elements; kDict: the values
  std::vector<std::string> keys;  // kDict: the keys, parallel to items

  const PyValue* Find(const std::string& key) const {
    for (size_t i = 0; i < keys.size(); ++i) {
      if (keys[i] == key) return &items[i];
    }
    return nullptr;
  }
};

class PyLiteralReader {
 public:
  // `wanted`: the top-level keys whose values are kept.
  PyLiteralReader(const std::string& text, const std::string& path, std::vector<std::string> wanted)
      : s_(text), path_(path), wanted_(std::move(wanted)) {}

  // The whole text: one dict, then nothing but blanks and comments.
  PyValue Document() {
    SkipBlank();
    if (i_ >= s_.size()) Fail("empty: not an mrcal .cameramodel (a Python dict)");
    if (s_[i_] != '{') Fail("not a Python dict: an mrcal .cameramodel starts with '{'");
    PyValue root = Value(1, true);
    key_.clear();
    SkipBlank();
    if (i_ < s_.size()) Fail(fmt::format("'{}' after the dict's closing '}}'", Shown(s_.substr(i_), 24)));
    return root;
  }

 private:
  [[noreturn]] void Fail(const std::string& problem) const {
    const auto line =
        1 + std::count(s_.begin(), s_.begin() + static_cast<std::ptrdiff_t>(std::min(i_, s_.size())), '\n');
    throw util::InputError(key_.empty() ? fmt::format("{}: line {}: {}", path_, line, problem)
                                        : fmt::format("{}: {}: line {}: {}", path_, key_, line, problem));
  }
  bool At(char c) const { return i_ < s_.size() && s_[i_] == c; }

  void SkipBlank() {
    while (i_ < s_.size()) {
      const char c = s_[i_];
      if (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f') {
        ++i_;
      } else if (c == '#') {
        while (i_ < s_.size() && s_[i_] != '\n') ++i_;
      } else if (c == '\\' && i_ + 1 < s_.size() && s_[i_ + 1] == '\n') {
        i_ += 2;  // an explicit line continuation
      } else {
        return;
      }
    }
  }

  // A value; with `keep` false only its syntax is checked and an empty value of its kind returned.
  PyValue Value(int depth, bool keep) {
    if (depth > kMaxLiteralDepth) Fail(fmt::format("nested deeper than {} levels", kMaxLiteralDepth));
    SkipBlank();
    if (i_ >= s_.size()) Fail("the file ends where a value should be");
    if (keep && ++kept_ > kMaxKeptValues) Fail(fmt::format("more than {} values", kMaxKeptValues));
    const char c = s_[i_];
    if (c == '{') return Dict(depth, keep);
    if (c == '[') return Sequence(']', depth, keep);
    if (c == '(') return Sequence(')', depth, keep);
    if (c == '\'' || c == '"') return String(false, keep);
    if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
      size_t j = i_;
      while (j < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[j])) || s_[j] == '_')) ++j;
      std::string word = s_.substr(i_, j - i_);
      for (char& w : word) w = static_cast<char>(std::tolower(static_cast<unsigned char>(w)));
      if (j < s_.size() && (s_[j] == '\'' || s_[j] == '"') &&
          (word == "r" || word == "b" || word == "u" || word == "br" || word == "rb")) {
        i_ = j;
        return String(word.find('r') != std::string::npos, keep);
      }
      const std::string name = s_.substr(i_, j - i_);
      if (name != "None" && name != "True" && name != "False") {
        Fail(fmt::format("'{}' is not a Python literal (a number, string, list, tuple, dict, None, True or False)",
                         Shown(name)));
      }
      i_ = j;
      PyValue v;
      v.text = name;
      return v;
    }
    if (std::isdigit(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '+') return Number();
    Fail(fmt::format("'{}' cannot start a value", Shown(std::string(1, c))));
  }

  // A quoted string from its opening quote; `raw` keeps backslashes (which still cannot end the string).
  PyValue String(bool raw, bool keep) {
    const char q = s_[i_];
    const std::string triple(3, q);
    const size_t quote_len = s_.compare(i_, 3, triple) == 0 ? 3 : 1;
    i_ += quote_len;
    PyValue v;
    v.kind = PyValue::Kind::kString;
    for (;;) {
      if (i_ >= s_.size()) Fail("a string is not closed");
      const char c = s_[i_];
      if (c == '\\' && i_ + 1 < s_.size()) {
        const char next = s_[i_ + 1];
        if (keep && (raw || (next != '\\' && next != '\'' && next != '"'))) v.text += c;
        if (keep) v.text += next;
        i_ += 2;
      } else if (c == q && (quote_len == 1 || s_.compare(i_, 3, triple) == 0)) {
        i_ += quote_len;
        return v;
      } else if (c == '\n' && quote_len == 1) {
        Fail("a string is not closed on its line");
      } else {
        if (keep) v.text += c;
        ++i_;
      }
    }
  }

  // A decimal int or float with an optional sign. from_chars reads it correctly rounded (the value mrcal or topocal
  // wrote with enough digits comes back to the bit); nan, inf, hex and 1e999 are refused.
  PyValue Number() {
    const size_t start = i_;
    const bool negative = s_[i_] == '-';
    if (s_[i_] == '-' || s_[i_] == '+') ++i_;
    const size_t digits = i_;
    while (i_ < s_.size()) {
      const char c = s_[i_];
      const bool exponent_sign = (c == '+' || c == '-') && (s_[i_ - 1] == 'e' || s_[i_ - 1] == 'E');
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && !exponent_sign) break;
      ++i_;
    }
    const std::string token = s_.substr(start, i_ - start);
    double value = 0;
    const char* const end = s_.data() + i_;
    const auto [stop, error] = std::from_chars(s_.data() + digits, end, value);
    if (digits == i_ || !(std::isdigit(static_cast<unsigned char>(s_[digits])) || s_[digits] == '.') || stop != end ||
        error == std::errc::invalid_argument) {
      Fail(fmt::format("'{}' is not a decimal number", Shown(token)));
    }
    if (error == std::errc::result_out_of_range || !std::isfinite(value)) {
      Fail(fmt::format("{} is beyond the range of a double (non-finite)", Shown(token)));
    }
    PyValue v;
    v.kind = PyValue::Kind::kNumber;
    v.number = negative ? -value : value;
    v.integral = token.find_first_of(".eE") == std::string::npos;
    return v;
  }

  // A list or tuple from its opening bracket; a trailing comma is allowed.
  PyValue Sequence(char close, int depth, bool keep) {
    ++i_;
    PyValue v;
    v.kind = PyValue::Kind::kSequence;
    for (;;) {
      SkipBlank();
      if (At(close)) break;
      PyValue item = Value(depth + 1, keep);
      if (keep) v.items.push_back(std::move(item));
      SkipBlank();
      if (At(',')) {
        ++i_;
      } else if (!At(close)) {
        Fail(fmt::format("expected ',' or '{}'", close));
      }
    }
    ++i_;
    return v;
  }

  // A dict from its '{': string keys. At the top level (depth 1) each key once, the key being read names every
  // message, and only the wanted keys' values are kept.
  PyValue Dict(int depth, bool keep) {
    ++i_;
    PyValue v;
    v.kind = PyValue::Kind::kDict;
    const bool top = depth == 1;
    std::set<std::string> seen;
    for (;;) {
      SkipBlank();
      if (At('}')) break;
      if (!At('\'') && !At('"')) Fail("expected a quoted key or '}'");
      std::string key = String(false, keep).text;
      if (top) {
        key_ = Shown(key);
        if (!seen.insert(key).second) Fail("the key appears twice (which one is meant?)");
      }
      const bool keep_value = top ? std::find(wanted_.begin(), wanted_.end(), key) != wanted_.end() : keep;
      SkipBlank();
      if (!At(':')) Fail("expected ':' after the key");
      ++i_;
      PyValue value = Value(depth + 1, keep_value);
      if (keep_value) {
        v.items.push_back(std::move(value));
        v.keys.push_back(std::move(key));
      }
      SkipBlank();
      if (At(',')) {
        ++i_;
      } else if (!At('}')) {
        Fail("expected ',' or '}'");
      }
    }
    ++i_;
    return v;
  }

  const std::string& s_;
  const std::string& path_;
  const std::vector<std::string> wanted_;
  size_t i_ = 0;
  size_t kept_ = 0;  // values kept so far
  std::string key_;  // the top-level key whose value is being read
};

const PyValue& MrcalKey(const PyValue& root, const std::string& path, const std::string& key) {
  const PyValue* v = root.Find(key);
  if (!v) Bad(path, key, "missing: not an mrcal .cameramodel");
  return *v;
}

std::vector<double> MrcalNumbers(const PyValue& root, const std::string& path, const std::string& key) {
  const PyValue& v = MrcalKey(root, path, key);
  if (v.kind != PyValue::Kind::kSequence) Bad(path, key, "not a list of numbers");
  std::vector<double> out;
  for (const PyValue& item : v.items) {
    if (item.kind != PyValue::Kind::kNumber) Bad(path, key, "not a list of numbers");
    out.push_back(item.number);
  }
  return out;
}

// The number of distortion coefficients of the mrcal lens models of OpenCV's family; -1 for the others. The pinhole
// and OPENCV4 (Brown without k3) are held by the smallest lens model too.
int MrcalDistortionCount(const std::string& lensmodel) {
  if (lensmodel == "LENSMODEL_PINHOLE") return 0;
  if (lensmodel == "LENSMODEL_OPENCV4") return 4;
  if (const auto lens = model::LensModelFromName(lensmodel, model::LensNaming::kMrcal)) {
    return model::LensParameterCount(*lens);
  }
  return -1;
}

}  // namespace

model::CameraModel ReadKalibrCamchain(const std::string& path, const std::string& camera_key) {
  const cv::FileStorage fs = OpenToolYaml(path);
  return ReadFileStorage(path, "a Kalibr camchain", [&]() -> model::CameraModel {
    if (!fs.isOpened() || !fs.root().isMap()) Bad(path, "file", "not a YAML mapping (a Kalibr camchain has cam0: ...)");
    const cv::FileNode cam = fs[camera_key];
    if (cam.empty()) Bad(path, camera_key, "missing: not a Kalibr camchain, or no such camera");
    if (!cam.isMap()) Bad(path, camera_key, "not a mapping");
    YamlSection section(cam, path, camera_key + ".");
    const std::string model_name = section.String("camera_model");
    if (model_name != "pinhole") {
      section.Fail("camera_model",
          fmt::format("'{}': only pinhole is supported (OpenCV's model)", Shown(model_name)));
    }
    const std::string distortion = section.String("distortion_model");
    if (distortion != "radtan") {
      section.Fail("distortion_model",
          fmt::format("'{}': only radtan is supported (equidistant is a fisheye model topocal does not fit)",
                      Shown(distortion)));
    }
    const auto intrinsics = section.Numbers("intrinsics", 4);
    const auto coeffs = section.Numbers("distortion_coeffs", 4);
    const auto resolution = section.Numbers("resolution", 2);
    model::CameraModel c;
    for (int i = 0; i < 2; ++i) {
      const double v = resolution[static_cast<size_t>(i)];
      if (!(v >= 1) || v != std::floor(v) || v > std::numeric_limits<int>::max()) {
        section.Fail("resolution", "must be two positive integers [width, height]");
      }
    }
    c.width_px = static_cast<int>(resolution[0]);
    c.height_px = static_cast<int>(resolution[1]);
    if (!(intrinsics[0] > 0 && intrinsics[1] > 0)) section.Fail("intrinsics", "focal lengths fu, fv must be > 0");
    c.fx_px = intrinsics[0];
    c.fy_px = intrinsics[1];
    c.cx_px = intrinsics[2];
    c.cy_px = intrinsics[3];
    c.dist = {coeffs[0], coeffs[1], coeffs[2], coeffs[3], 0.0};
    return c;
  });
}

model::CameraModel ReadRosCameraInfo(const std::string& path) {
  const cv::FileStorage fs = OpenToolYaml(path);
  return ReadFileStorage(path, "a ROS camera_info", [&]() -> model::CameraModel {
    if (!fs.isOpened() || !fs.root().isMap()) {
      Bad(path, "file", "not a YAML mapping (a ROS camera_info has image_width: ...)");
    }
    YamlSection root(fs.root(), path);
    model::CameraModel c;
    c.width_px = root.PositiveInt("image_width");
    c.height_px = root.PositiveInt("image_height");
    const std::vector<double> k = ReadRosMatrix(root, "camera_matrix", 3, 3);
    if (k[1] != 0 || k[3] != 0 || k[6] != 0 || k[7] != 0 || k[8] != 1) {
      Bad(path, "camera_matrix", "not a pinhole camera matrix [fx 0 cx; 0 fy cy; 0 0 1]");
    }
    c.fx_px = k[0];
    c.fy_px = k[4];
    c.cx_px = k[2];
    c.cy_px = k[5];
    RequirePhysicalCamera(c, path, "camera_matrix");
    std::tie(c.lens, c.dist) = ReadRosDistortion(root);
    return c;
  });
}

model::CameraModel ReadMrcalCameraModel(const std::string& path) {
  const std::string text = util::ReadFile(path);
  if (text.size() > kMaxCameraModelBytes) {
    Bad(path, "file",
        fmt::format("{} bytes: larger than the {} MiB an mrcal .cameramodel may have", text.size(),
                    kMaxCameraModelBytes >> 20));
  }
  const PyValue root = PyLiteralReader(text, path, {"lensmodel", "intrinsics", "imagersize"}).Document();
  const PyValue& lens = MrcalKey(root, path, "lensmodel");
  if (lens.kind != PyValue::Kind::kString) Bad(path, "lensmodel", "not a string");
  const int n = MrcalDistortionCount(lens.text);
  if (n < 0) {
    Bad(path, "lensmodel",
        fmt::format("'{}' is not a model topocal holds (OpenCV's): accepted are LENSMODEL_PINHOLE, "
                    "LENSMODEL_OPENCV4, {}",
                    Shown(lens.text), model::LensModelNames(", ", model::LensNaming::kMrcal)));
  }
  const std::vector<double> in = MrcalNumbers(root, path, "intrinsics");
  if (in.size() != static_cast<size_t>(4 + n)) {
    Bad(path, "intrinsics",
        fmt::format("{} has {} numbers (fx fy cx cy and {} distortion coefficients), found {}", lens.text, 4 + n, n,
                    in.size()));
  }
  const PyValue& size = MrcalKey(root, path, "imagersize");
  const bool size_ok = size.kind == PyValue::Kind::kSequence && size.items.size() == 2 &&
                       std::all_of(size.items.begin(), size.items.end(), [](const PyValue& v) {
                         return v.kind == PyValue::Kind::kNumber && v.integral && v.number >= 1 &&
                                v.number <= std::numeric_limits<int>::max();
                       });
  if (!size_ok) Bad(path, "imagersize", "must be two positive integers [width, height]");
  model::CameraModel c;
  c.width_px = static_cast<int>(size.items[0].number);
  c.height_px = static_cast<int>(size.items[1].number);
  c.fx_px = in[0];
  c.fy_px = in[1];
  c.cx_px = in[2];
  c.cy_px = in[3];
  for (int i = 0; i < n; ++i) c.dist[static_cast<size_t>(i)] = in[static_cast<size_t>(4 + i)];
  c.lens = model::SmallestLensModelFor(c.dist);
  RequirePhysicalCamera(c, path, "intrinsics");
  return c;
}

std::string ImportCalibrationText(const std::string& from, const std::string& path, const std::string& camera_key) {
  model::CameraModel camera;
  if (from == "kalibr") {
    camera = ReadKalibrCamchain(path, camera_key);
  } else if (from == "opencv") {
    camera = LoadCalibrationFile(path).opencv_camera;
  } else if (from == "mrcal") {
    camera = ReadMrcalCameraModel(path);
  } else if (from == "ros") {
    camera = ReadRosCameraInfo(path);
  } else {
    throw util::InputError(fmt::format("--from: '{}' is not kalibr, opencv, mrcal or ros", from));
  }
  std::string text = OpenCvCalibrationText(camera, from + ": " + path);
  // Read back by the reader every --calibration goes through: a file the other verbs would refuse (k1 = 1e308 has no
  // valid region) is not written.
  try {
    (void)ParseCalibrationFile(text, path);
  } catch (const util::InputError& e) {
    throw util::InputError(fmt::format("{} (the camera imported from it: nothing written)", e.what()));
  }
  return text;
}

}  // namespace topocal::calib

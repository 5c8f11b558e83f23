#include "report/unit_record_reader.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <span>
#include <sstream>

#include "model/io.h"
#include "model/json_section.h"
#include "model/sha256.h"
#include "model/spots_csv.h"
#include "model/version.h"

namespace topocal::report {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kUnitJson = "unit.json";
constexpr const char* kCalibrationYaml = "calibration.yaml";
constexpr const char* kResidualsCsv = "residuals.csv";
constexpr const char* kResidualsHeader = "view,image,corner_id,x_px,y_px,dx_px,dy_px,outlier";
constexpr std::size_t kSha256HexDigits = 64;

// Strict access to unit.json: every failure names the file and the dotted key.
class JsonReader {
 public:
  explicit JsonReader(std::string path) : path_(std::move(path)) {}

  [[noreturn]] void Fail(const std::string& key, const std::string& problem) const {
    throw model::InputError(fmt::format("{}: {}: {}", path_, key, problem));
  }

  const json& Member(const json& obj, const std::string& prefix, const char* name) const {
    const std::string key = Join(prefix, name);
    if (!obj.is_object()) Fail(prefix, "must be an object");
    const auto it = obj.find(name);
    if (it == obj.end()) Fail(key, "missing");
    return *it;
  }
  bool Has(const json& obj, const char* name) const { return obj.is_object() && obj.contains(name); }

  const json& Object(const json& obj, const std::string& prefix, const char* name) const {
    const json& v = Member(obj, prefix, name);
    if (!v.is_object()) Fail(Join(prefix, name), "must be an object");
    return v;
  }
  const json& Array(const json& obj, const std::string& prefix, const char* name) const {
    const json& v = Member(obj, prefix, name);
    if (!v.is_array()) Fail(Join(prefix, name), "must be an array");
    return v;
  }
  double Number(const json& obj, const std::string& prefix, const char* name) const {
    const json& v = Member(obj, prefix, name);
    if (!v.is_number()) Fail(Join(prefix, name), "must be a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) Fail(Join(prefix, name), "must be finite");
    return d;
  }
  int Integer(const json& obj, const std::string& prefix, const char* name) const {
    const json& v = Member(obj, prefix, name);
    if (!v.is_number_integer()) Fail(Join(prefix, name), "must be an integer");
    // get<int>() truncates silently (4294967297 became 1): the range is checked on the 64-bit value first.
    if (!model::JsonIntegerWithin(v, std::numeric_limits<int>::min(), std::numeric_limits<int>::max())) {
      Fail(Join(prefix, name), fmt::format("out of range (got {})", model::QuoteJsonValue(v)));
    }
    return v.get<int>();
  }
  int NonNegativeInteger(const json& obj, const std::string& prefix, const char* name) const {
    const int i = Integer(obj, prefix, name);
    if (i < 0) Fail(Join(prefix, name), "must not be negative");
    return i;
  }
  bool Bool(const json& obj, const std::string& prefix, const char* name) const {
    const json& v = Member(obj, prefix, name);
    if (!v.is_boolean()) Fail(Join(prefix, name), "must be true or false");
    return v.get<bool>();
  }
  std::string String(const json& obj, const std::string& prefix, const char* name) const {
    const json& v = Member(obj, prefix, name);
    if (!v.is_string()) Fail(Join(prefix, name), "must be a string");
    return v.get<std::string>();
  }
  std::string NonEmptyString(const json& obj, const std::string& prefix, const char* name) const {
    std::string s = String(obj, prefix, name);
    if (s.empty()) Fail(Join(prefix, name), "must not be empty");
    return s;
  }
  std::string Sha256(const json& obj, const std::string& prefix, const char* name) const {
    std::string s = String(obj, prefix, name);
    const bool hex = s.size() == kSha256HexDigits &&
                     s.find_first_not_of("0123456789abcdef") == std::string::npos;
    if (!hex) Fail(Join(prefix, name), "must be 64 lower-case hex digits (SHA-256)");
    return s;
  }

  static std::string Join(const std::string& prefix, const std::string& name) {
    return prefix.empty() ? name : prefix + "." + name;
  }
  static std::string Index(const std::string& prefix, std::size_t i) { return fmt::format("{}[{}]", prefix, i); }

 private:
  std::string path_;
};

StageValues ReadStage(const JsonReader& r, const json& parent, const std::string& prefix, const char* name,
                      std::span<const char* const> keys) {
  const json& obj = r.Object(parent, prefix, name);
  StageValues values;
  const std::string p = JsonReader::Join(prefix, name);
  for (const char* key : keys) values[key] = r.Number(obj, p, key);
  return values;
}

std::optional<UncertaintyBlock> ReadUncertainty(const JsonReader& r, const json& parent, const std::string& prefix) {
  // null: not propagated (--uncertainty 0, or no distortion parameter with a spread).
  if (!r.Has(parent, "uncertainty") || parent["uncertainty"].is_null()) return std::nullopt;
  const json& u = r.Object(parent, prefix, "uncertainty");
  const std::string p = JsonReader::Join(prefix, "uncertainty");
  UncertaintyBlock block;
  block.samples = r.NonNegativeInteger(u, p, "samples");
  block.seed = r.Integer(u, p, "seed");
  block.failed_samples = r.NonNegativeInteger(u, p, "failed_samples");
  const json& drawn = r.Array(u, p, "drawn");
  for (std::size_t i = 0; i < drawn.size(); ++i) {
    if (!drawn[i].is_string()) r.Fail(JsonReader::Index(JsonReader::Join(p, "drawn"), i), "must be a string");
    block.drawn.push_back(drawn[i].get<std::string>());
  }
  const json& q = r.Object(u, p, "quantities");
  const std::string qp = JsonReader::Join(p, "quantities");
  for (const char* key : {"rx_mm", "ry_mm", "kx", "ky", "alpha_deg", "pv_tangential_D", "pv_axial_D"}) {
    const json& one = r.Object(q, qp, key);
    const std::string kp = JsonReader::Join(qp, key);
    ExpandedUncertainty e{r.Number(one, kp, "mean"), r.Number(one, kp, "U")};
    if (e.U < 0) r.Fail(JsonReader::Join(kp, "U"), "must not be negative");
    block.quantities[key] = e;
  }
  // Optional: the sphere's radius and central power carried through the same draws.
  for (const char* key : {"radius_mm", "central_axial_power_D"}) {
    if (!r.Has(q, key)) continue;
    const json& one = r.Object(q, qp, key);
    const std::string kp = JsonReader::Join(qp, key);
    ExpandedUncertainty e{r.Number(one, kp, "mean"), r.Number(one, kp, "U")};
    if (e.U < 0) r.Fail(JsonReader::Join(kp, "U"), "must not be negative");
    block.quantities[key] = e;
  }
  return block;
}

// Sample standard deviation (n - 1) of the values of verification.repeatability.KEY.
double SampleStddev(const JsonReader& r, const json& rep, const char* key, std::size_t* count) {
  const json& a = r.Array(rep, "verification.repeatability", key);
  const std::string p = JsonReader::Join("verification.repeatability", key);
  if (a.size() < 2) r.Fail(p, "needs at least 2 repeated measurements");
  if (*count != 0 && a.size() != *count) r.Fail(p, "must have as many entries as radius_mm");
  *count = a.size();
  double sum = 0, sum2 = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!a[i].is_number() || !std::isfinite(a[i].get<double>())) r.Fail(JsonReader::Index(p, i), "must be a finite number");
    sum += a[i].get<double>();
  }
  const double mean = sum / static_cast<double>(a.size());
  for (const auto& x : a) sum2 += (x.get<double>() - mean) * (x.get<double>() - mean);
  return std::sqrt(sum2 / static_cast<double>(a.size() - 1));
}

std::optional<SphereRepeatability> ReadRepeatability(const JsonReader& r, const json& v) {
  if (!r.Has(v, "repeatability")) return std::nullopt;
  const json& rep = r.Object(v, "verification", "repeatability");
  std::size_t n = 0;
  SphereRepeatability out;
  out.radius_stddev_mm = SampleStddev(r, rep, "radius_mm", &n);
  out.power_stddev_D = SampleStddev(r, rep, "central_axial_power_D", &n);
  out.images = static_cast<int>(n);
  return out;
}

// A name in `files` must stay inside the record directory.
bool IsSafeRelativeName(const std::string& name) {
  if (name.empty() || name.front() == '/') return false;
  for (const auto& part : fs::path(name)) {
    if (part == ".." || part == ".") return false;
  }
  return true;
}

std::vector<std::string> SplitCsvLine(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  std::istringstream ss(line);
  while (std::getline(ss, field, ',')) fields.push_back(field);
  if (!line.empty() && line.back() == ',') fields.emplace_back();
  return fields;
}

double ParseCsvNumber(const std::string& path, int line_no, const char* column, const std::string& text) {
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !std::isfinite(v)) {
    throw model::InputError(fmt::format("{}: line {}: {}: not a finite number: '{}'", path, line_no, column, text));
  }
  return v;
}

std::vector<CornerResidualRow> ReadResiduals(const std::string& path) {
  std::istringstream in(model::ReadFile(path));
  std::string line;
  if (!std::getline(in, line) || (line.erase(line.find_last_not_of("\r") + 1), line != kResidualsHeader)) {
    throw model::InputError(fmt::format("{}: header: must be '{}'", path, kResidualsHeader));
  }
  std::vector<CornerResidualRow> rows;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    const std::vector<std::string> f = SplitCsvLine(line);
    if (f.size() != 8) {
      throw model::InputError(fmt::format("{}: line {}: expected 8 comma-separated fields, got {}", path, line_no,
                                          f.size()));
    }
    CornerResidualRow row;
    const double view = ParseCsvNumber(path, line_no, "view", f[0]);
    const double corner = ParseCsvNumber(path, line_no, "corner_id", f[2]);
    const double outlier = ParseCsvNumber(path, line_no, "outlier", f[7]);
    if (view < 0 || view != std::floor(view) || corner != std::floor(corner) || (outlier != 0 && outlier != 1)) {
      throw model::InputError(fmt::format("{}: line {}: view, corner_id must be integers and outlier 0 or 1", path,
                                          line_no));
    }
    row.view = static_cast<int>(view);
    row.image = f[1];
    row.corner_id = static_cast<int>(corner);
    row.x_px = ParseCsvNumber(path, line_no, "x_px", f[3]);
    row.y_px = ParseCsvNumber(path, line_no, "y_px", f[4]);
    row.dx_px = ParseCsvNumber(path, line_no, "dx_px", f[5]);
    row.dy_px = ParseCsvNumber(path, line_no, "dy_px", f[6]);
    row.outlier = outlier == 1;
    rows.push_back(row);
  }
  return rows;
}

}  // namespace

UnitRecord ReadUnitRecord(const std::string& directory) {
  UnitRecord rec;
  rec.directory = directory;
  if (!fs::is_directory(directory)) {
    throw model::InputError(fmt::format("{}: not a unit record directory (does not exist)", directory));
  }
  rec.unit_json_path = (fs::path(directory) / kUnitJson).string();
  if (!fs::is_regular_file(rec.unit_json_path)) {
    throw model::InputError(fmt::format("{}: missing: the unit record is incomplete", rec.unit_json_path));
  }
  const std::string text = model::ReadFile(rec.unit_json_path);
  rec.unit_json_sha256 = model::Sha256Hex(text);
  const json root = model::ParseJsonStrict(text, rec.unit_json_path);
  const JsonReader r(rec.unit_json_path);
  if (!root.is_object()) r.Fail("(top level)", "must be an object");

  // Identity and compatibility first: nothing else is read from a record of another format or version.
  const std::string format = r.String(root, "", "format");
  if (format != kUnitRecordFormat) r.Fail("format", fmt::format("'{}' is not '{}'", format, kUnitRecordFormat));
  rec.format_version = r.Integer(root, "", "format_version");
  if (rec.format_version != kUnitRecordFormatVersion) {
    r.Fail("format_version", fmt::format("{} is not supported (this reader reads {})", rec.format_version,
                                         kUnitRecordFormatVersion));
  }
  rec.tool_version = r.String(root, "", "tool_version");
  if (rec.tool_version != kVersion) {
    r.Fail("tool_version", fmt::format("the record was written by topocal {}, this is topocal {}: recalculate it "
                                       "with `topocal unit calibrate`",
                                       rec.tool_version, kVersion));
  }
  rec.serial = r.NonEmptyString(root, "", "serial");
  rec.created_utc = r.NonEmptyString(root, "", "created_utc");

  const json& settings = r.Object(root, "", "settings");
  rec.settings_model = r.NonEmptyString(settings, "settings", "model");
  rec.settings_single_view = r.Bool(settings, "settings", "single_view");
  rec.settings_fit_centre = r.Bool(settings, "settings", "fit_centre");
  if (r.Has(settings, "sphere_radius_mm")) rec.settings_sphere_radius_mm = r.Number(settings, "settings", "sphere_radius_mm");
  rec.settings_uncertainty_samples = r.NonNegativeInteger(settings, "settings", "uncertainty_samples");
  rec.settings_seed = r.Integer(settings, "settings", "seed");

  const json& inputs = r.Array(root, "", "inputs");
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    const std::string p = JsonReader::Index("inputs", i);
    rec.inputs.push_back({r.NonEmptyString(inputs[i], p, "role"), r.NonEmptyString(inputs[i], p, "path"),
                          r.Sha256(inputs[i], p, "sha256")});
  }

  // Completeness and integrity: every listed file exists with its digest.
  const json& files = r.Array(root, "", "files");
  std::set<std::string> names;
  for (std::size_t i = 0; i < files.size(); ++i) {
    const std::string p = JsonReader::Index("files", i);
    RecordFile f{r.NonEmptyString(files[i], p, "name"), r.Sha256(files[i], p, "sha256")};
    if (!IsSafeRelativeName(f.name)) r.Fail(JsonReader::Join(p, "name"), fmt::format("'{}' is not a path inside the record", f.name));
    if (!names.insert(f.name).second) r.Fail(JsonReader::Join(p, "name"), fmt::format("'{}' is listed twice", f.name));
    const std::string path = (fs::path(directory) / f.name).string();
    if (!fs::is_regular_file(path)) {
      throw model::InputError(fmt::format("{}: missing (listed in {} files[{}]): the unit record is incomplete", path,
                                          rec.unit_json_path, i));
    }
    const std::string actual = model::Sha256HexOfFile(path);
    if (actual != f.sha256) {
      throw model::InputError(fmt::format("{}: SHA-256 {} differs from {} in {} files[{}]: the file was changed after "
                                          "the record was written",
                                          path, actual, f.sha256, rec.unit_json_path, i));
    }
    rec.files.push_back(f);
  }
  for (const char* required : {kCalibrationYaml, kResidualsCsv}) {
    if (!names.count(required)) {
      const std::string path = (fs::path(directory) / required).string();
      throw model::InputError(fs::exists(path)
                                  ? fmt::format("{}: files: '{}' is not listed, so it cannot be verified",
                                                rec.unit_json_path, required)
                                  : fmt::format("{}: missing: the unit record is incomplete", path));
    }
  }

  const json& camera = r.Object(root, "", "camera");
  rec.camera_pixel_pitch_um = r.Number(camera, "camera", "pixel_pitch_um");
  rec.camera_width_px = r.Integer(camera, "camera", "width_px");
  rec.camera_height_px = r.Integer(camera, "camera", "height_px");
  rec.camera_a_mm = r.Number(camera, "camera", "a_mm");

  const json& cal = r.Object(root, "", "calibration");
  rec.calibration_model = r.NonEmptyString(cal, "calibration", "model");
  rec.calibration_single_view = r.Bool(cal, "calibration", "single_view");
  rec.calibration_width_px = r.Integer(cal, "calibration", "image_width_px");
  rec.calibration_height_px = r.Integer(cal, "calibration", "image_height_px");
  if (rec.calibration_width_px <= 0 || rec.calibration_height_px <= 0) {
    r.Fail("calibration.image_width_px", "the image size must be positive");
  }
  rec.calibration_rms_px = r.Number(cal, "calibration", "rms_px");
  if (rec.calibration_rms_px < 0) r.Fail("calibration.rms_px", "must not be negative");
  rec.corners_used = r.NonNegativeInteger(cal, "calibration", "corners_used");
  rec.outliers = r.NonNegativeInteger(cal, "calibration", "outliers");
  const json& params = r.Array(cal, "calibration", "parameters");
  if (params.empty()) r.Fail("calibration.parameters", "must not be empty");
  for (std::size_t i = 0; i < params.size(); ++i) {
    const std::string p = JsonReader::Index("calibration.parameters", i);
    CalibrationParameter cp{r.NonEmptyString(params[i], p, "name"), r.Number(params[i], p, "value"),
                            r.Number(params[i], p, "stddev"), r.Bool(params[i], p, "fixed")};
    if (cp.stddev < 0) r.Fail(JsonReader::Join(p, "stddev"), "must not be negative");
    rec.parameters.push_back(cp);
  }
  if (r.Has(cal, "seidel")) {
    const json& s = r.Object(cal, "calibration", "seidel");
    rec.seidel_sigma_per_mm2 = r.Number(s, "calibration.seidel", "sigma_per_mm2");
    rec.seidel_sigma_stddev_per_mm2 = r.Number(s, "calibration.seidel", "sigma_stddev_per_mm2");
    rec.seidel_magnification = r.Number(s, "calibration.seidel", "magnification");
    rec.seidel_focal_mm = r.Number(s, "calibration.seidel", "focal_mm");
  }
  if (r.Has(cal, "distortion_field")) {
    const json& df = r.Object(cal, "calibration", "distortion_field");
    if (r.Has(df, "field_radius_px")) {
      rec.field_radius_px = r.Number(df, "calibration.distortion_field", "field_radius_px");
      if (*rec.field_radius_px <= 0) r.Fail("calibration.distortion_field.field_radius_px", "must be positive");
    }
  }
  const json& views = r.Array(cal, "calibration", "views");
  if (views.empty()) r.Fail("calibration.views", "must not be empty");
  for (std::size_t i = 0; i < views.size(); ++i) {
    const std::string p = JsonReader::Index("calibration.views", i);
    ViewRms v{r.String(views[i], p, "image"), r.Number(views[i], p, "rms_px"),
              r.NonNegativeInteger(views[i], p, "corners")};
    if (v.rms_px < 0) r.Fail(JsonReader::Join(p, "rms_px"), "must not be negative");
    rec.views.push_back(v);
  }

  if (r.Has(root, "verification")) {
    const json& v = r.Object(root, "", "verification");
    SphereVerification s;
    s.image = r.String(v, "verification", "image");
    s.radius_true_mm = r.Number(v, "verification", "radius_true_mm");
    if (s.radius_true_mm <= 0) r.Fail("verification.radius_true_mm", "must be positive");
    s.power_true_D = r.Number(v, "verification", "power_true_D");
    s.keratometric_index = r.Number(v, "verification", "keratometric_index");
    s.uncorrected = ReadStage(r, v, "verification", "uncorrected", kSphereStageKeys);
    s.corrected = ReadStage(r, v, "verification", "corrected", kSphereStageKeys);
    for (auto [key, count] :
         {std::pair{"spots_unassigned", &s.spots_unassigned}, std::pair{"spots_missing", &s.spots_missing}}) {
      if (r.Has(v, key)) *count = r.NonNegativeInteger(v, "verification", key);
    }
    s.uncertainty = ReadUncertainty(r, v, "verification");
    s.repeatability = ReadRepeatability(r, v);
    rec.verification = std::move(s);
  }
  const json& paper = r.Object(root, "", "paper_cornea");
  rec.paper.truth = ReadStage(r, paper, "paper_cornea", "truth", kPaperTruthKeys);
  rec.paper.uncorrected = ReadStage(r, paper, "paper_cornea", "uncorrected", kPaperStageKeys);
  rec.paper.corrected = ReadStage(r, paper, "paper_cornea", "corrected", kPaperStageKeys);
  rec.paper.uncertainty = ReadUncertainty(r, paper, "paper_cornea");

  if (r.Has(root, "device")) {
    // The device itself comes from device.json (its digest is checked below with every file); unit.json's copy of
    // the parameters is not trusted for anything the report shows.
    const json& d = r.Object(root, "", "device");
    DeviceStageRecord dev;
    const json& paper_dev = r.Object(d, "device", "paper_cornea");
    for (const char* stage : kThreeWayStages) {
      dev.paper[stage] = ReadStage(r, paper_dev, "device.paper_cornea", stage, kDeviceStageKeys);
    }
    if (r.Has(d, "held_out_ball")) {
      const json& h = r.Object(d, "device", "held_out_ball");
      dev.held_out_radius_true_mm = r.Number(h, "device.held_out_ball", "radius_true_mm");
      dev.held_out_power_true_D = r.Number(h, "device.held_out_ball", "power_true_D");
      for (const char* stage : kThreeWayStages) {
        dev.held_out[stage] = ReadStage(r, h, "device.held_out_ball", stage, kDeviceStageKeys);
      }
    }
    rec.device = std::move(dev);
  }

  // The design and camera the record was computed with (canonical form), for the report's recomputation.
  if (r.Has(root, "configuration")) {
    const json& c = r.Object(root, "", "configuration");
    const std::string origin = rec.unit_json_path + ": configuration";
    rec.config = model::ParseConfig(r.Object(c, "configuration", "design").dump(), origin + ".design");
    rec.topographer_camera =
        model::ParseTopographerCamera(r.Object(c, "configuration", "camera").dump(), origin + ".camera");
  }

  // The files, now known to be the ones the record was written with.
  rec.calibration_path = (fs::path(directory) / kCalibrationYaml).string();
  rec.calibration = calib::LoadCalibrationFile(rec.calibration_path);
  if (rec.calibration.camera.width_px != rec.calibration_width_px ||
      rec.calibration.camera.height_px != rec.calibration_height_px) {
    r.Fail("calibration.image_width_px", fmt::format("{} x {} px differs from {} ({} x {} px)",
                                                     rec.calibration_width_px, rec.calibration_height_px,
                                                     rec.calibration_path, rec.calibration.camera.width_px,
                                                     rec.calibration.camera.height_px));
  }
  rec.residuals = ReadResiduals((fs::path(directory) / kResidualsCsv).string());
  if (rec.device) {
    const auto listed = std::find_if(rec.files.begin(), rec.files.end(), [](const RecordFile& f) { return f.name == "device.json"; });
    if (listed == rec.files.end()) r.Fail("device", "the record has a device stage but no device.json in files");
    rec.device->file = model::LoadDevice((fs::path(directory) / "device.json").string());
  }
  if (rec.verification) {
    const auto listed =
        std::find_if(rec.files.begin(), rec.files.end(), [](const RecordFile& f) { return f.name == kSphereSpotsCsv; });
    if (listed != rec.files.end()) {
      rec.verification->detected = model::ReadSpotsCsv((fs::path(directory) / kSphereSpotsCsv).string());
    }
  }
  for (const RecordFile& f : rec.files) {
    const fs::path name(f.name);
    if (name.parent_path() == "maps" && name.extension() == ".png") {
      rec.map_png[name.filename().string()] = model::ReadFile((fs::path(directory) / f.name).string());
    }
  }
  return rec;
}

}  // namespace topocal::report

#include "report/unit_record_reader.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <span>
#include <sstream>

#include "model/spots_csv.h"
#include "util/io.h"
#include "util/json_section.h"
#include "util/median.h"
#include "util/sha256.h"
#include "util/version.h"

namespace topocal::report {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kUnitJson = "unit.json";
constexpr const char* kCalibrationYaml = "calibration.yaml";
constexpr const char* kResidualsCsv = "residuals.csv";
constexpr const char* kResidualsHeader = "view,image,corner_id,x_px,y_px,dx_px,dy_px,outlier";
constexpr std::size_t kSha256HexDigits = 64;

using util::JsonSection;

// unit.json is read with the project's one strict JSON reader (util/json_section.h): every failure is one line
// "unit.json: KEY: problem" naming the file and the dotted key. Unknown keys are allowed (a record may carry more
// than the report reads), so RejectUnknown() is not called.
std::string Sha256(JsonSection& s, const std::string& k) {
  std::string v = s.String(k);
  const bool hex = v.size() == kSha256HexDigits && v.find_first_not_of("0123456789abcdef") == std::string::npos;
  if (!hex) s.Fail(s.Key(k), "must be 64 lower-case hex digits (SHA-256)");
  return v;
}

StageValues ReadStage(JsonSection& parent, const char* name, std::span<const char* const> keys) {
  JsonSection obj = parent.Child(name);
  StageValues values;
  for (const char* key : keys) values[key] = obj.Number(key);
  return values;
}

ExpandedUncertainty ReadExpanded(JsonSection& quantities, const char* key) {
  JsonSection one = quantities.Child(key);
  return ExpandedUncertainty{one.Number("mean"), one.NonNegativeNumber("U")};
}

std::optional<UncertaintyBlock> ReadUncertainty(JsonSection& parent) {
  // null: not propagated (--uncertainty 0, or no distortion parameter with a spread).
  if (parent.AbsentOrNull("uncertainty")) return std::nullopt;
  JsonSection u = parent.Child("uncertainty");
  UncertaintyBlock block;
  const std::string method = u.NonEmptyString("method");
  if (method != "linear" && method != "monte-carlo") u.Fail(u.Key("method"), "must be linear or monte-carlo");
  block.linear = method == "linear";
  block.samples = u.NonNegativeInteger("samples");
  block.seed = u.Integer("seed");
  block.failed_samples = u.NonNegativeInteger("failed_samples");
  const json& drawn = u.Array("drawn");
  for (std::size_t i = 0; i < drawn.size(); ++i) {
    if (!drawn[i].is_string()) u.Fail(fmt::format("{}[{}]", u.Key("drawn"), i), "must be a string");
    block.drawn.push_back(drawn[i].get<std::string>());
  }
  JsonSection q = u.Child("quantities");
  for (const char* key : {"rx_mm", "ry_mm", "kx", "ky", "alpha_deg", "pv_tangential_D", "pv_axial_D"}) {
    block.quantities[key] = ReadExpanded(q, key);
  }
  // Optional: the sphere's radius and central power carried through the same draws.
  for (const char* key : {"radius_mm", "central_axial_power_D"}) {
    if (q.Has(key)) block.quantities[key] = ReadExpanded(q, key);
  }
  return block;
}

// Sample standard deviation (n - 1) of the values of verification.repeatability.KEY.
double SampleStddev(JsonSection& rep, const char* key, std::size_t* count) {
  const json& a = rep.Array(key);
  const std::string p = rep.Key(key);
  if (a.size() < 2) rep.Fail(p, "needs at least 2 repeated measurements");
  if (*count != 0 && a.size() != *count) rep.Fail(p, "must have as many entries as radius_mm");
  *count = a.size();
  std::vector<double> values;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!a[i].is_number() || !std::isfinite(a[i].get<double>())) {
      rep.Fail(fmt::format("{}[{}]", p, i), "must be a finite number");
    }
    values.push_back(a[i].get<double>());
  }
  return util::SampleStddev(values);
}

std::optional<SphereRepeatability> ReadRepeatability(JsonSection& v) {
  if (!v.Has("repeatability")) return std::nullopt;
  JsonSection rep = v.Child("repeatability");
  std::size_t n = 0;
  SphereRepeatability out;
  out.radius_stddev_mm = SampleStddev(rep, "radius_mm", &n);
  out.power_stddev_D = SampleStddev(rep, "central_axial_power_D", &n);
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
    throw util::InputError(fmt::format("{}: line {}: {}: not a finite number: '{}'", path, line_no, column, text));
  }
  return v;
}

std::vector<CornerResidualRow> ReadResiduals(const std::string& path) {
  std::istringstream in(util::ReadFile(path));
  std::string line;
  if (!std::getline(in, line) || (line.erase(line.find_last_not_of("\r") + 1), line != kResidualsHeader)) {
    throw util::InputError(fmt::format("{}: header: must be '{}'", path, kResidualsHeader));
  }
  std::vector<CornerResidualRow> rows;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    const std::vector<std::string> f = SplitCsvLine(line);
    if (f.size() != 8) {
      throw util::InputError(
          fmt::format("{}: line {}: expected 8 comma-separated fields, got {}", path, line_no, f.size()));
    }
    CornerResidualRow row;
    const double view = ParseCsvNumber(path, line_no, "view", f[0]);
    const double corner = ParseCsvNumber(path, line_no, "corner_id", f[2]);
    const double outlier = ParseCsvNumber(path, line_no, "outlier", f[7]);
    if (view < 0 || view != std::floor(view) || corner != std::floor(corner) || (outlier != 0 && outlier != 1)) {
      throw util::InputError(
          fmt::format("{}: line {}: view, corner_id must be integers and outlier 0 or 1", path, line_no));
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

// Identity and compatibility first: nothing else is read from a record of another format or version.
void ReadIdentity(JsonSection& r, UnitRecord* rec) {
  const std::string format = r.String("format");
  if (format != kUnitRecordFormat) r.Fail("format", fmt::format("'{}' is not '{}'", format, kUnitRecordFormat));
  rec->format_version = r.Integer("format_version");
  if (rec->format_version != kUnitRecordFormatVersion) {
    r.Fail("format_version", fmt::format("{} is not supported (this reader reads {})", rec->format_version,
                                         kUnitRecordFormatVersion));
  }
  rec->tool_version = r.String("tool_version");
  if (rec->tool_version != kVersion) {
    r.Fail("tool_version", fmt::format("the record was written by topocal {}, this is topocal {}: recalculate it "
                                       "with `topocal unit calibrate`",
                                       rec->tool_version, kVersion));
  }
  if (r.Has("tool_commit")) rec->tool_commit = r.NonEmptyString("tool_commit");  // absent in older records
  rec->serial = r.NonEmptyString("serial");
  rec->created_utc = r.NonEmptyString("created_utc");
}

void ReadSettingsAndInputs(JsonSection& r, UnitRecord* rec) {
  JsonSection settings = r.Child("settings");
  rec->settings_model = settings.NonEmptyString("model");
  rec->settings_single_view = settings.Bool("single_view");
  rec->settings_fit_centre = settings.Bool("fit_centre");
  if (settings.Has("sphere_radius_mm")) rec->settings_sphere_radius_mm = settings.Number("sphere_radius_mm");
  const int draws = settings.NonNegativeInteger("uncertainty_samples");
  const std::string method = settings.NonEmptyString("uncertainty");
  const auto uncertainty = pipeline::UncertaintySetting::FromName(method, draws);
  if (!uncertainty) settings.Fail(settings.Key("uncertainty"), pipeline::UncertaintySetting::WhyNot(method, draws));
  rec->settings_uncertainty = *uncertainty;
  rec->settings_seed = settings.Integer("seed");

  const std::size_t n_inputs = r.Array("inputs").size();
  for (std::size_t i = 0; i < n_inputs; ++i) {
    JsonSection in = r.Element("inputs", i);
    rec->inputs.push_back({in.NonEmptyString("role"), in.NonEmptyString("path"), Sha256(in, "sha256")});
  }
}

// Completeness and integrity: every listed file exists with its digest.
void ReadAndVerifyFiles(JsonSection& r, const std::string& directory, UnitRecord* rec) {
  const std::size_t n_files = r.Array("files").size();
  std::set<std::string> names;
  for (std::size_t i = 0; i < n_files; ++i) {
    JsonSection fj = r.Element("files", i);
    RecordFile f{fj.NonEmptyString("name"), Sha256(fj, "sha256")};
    if (!IsSafeRelativeName(f.name))
      fj.Fail(fj.Key("name"), fmt::format("'{}' is not a path inside the record", f.name));
    if (!names.insert(f.name).second) fj.Fail(fj.Key("name"), fmt::format("'{}' is listed twice", f.name));
    const std::string path = (fs::path(directory) / f.name).string();
    if (!fs::is_regular_file(path)) {
      throw util::InputError(fmt::format("{}: missing (listed in {} files[{}]): the unit record is incomplete", path,
                                         rec->unit_json_path, i));
    }
    const std::string actual = util::Sha256HexOfFile(path);
    if (actual != f.sha256) {
      throw util::InputError(
          fmt::format("{}: SHA-256 {} differs from {} in {} files[{}]: the file was changed after "
                      "the record was written",
                      path, actual, f.sha256, rec->unit_json_path, i));
    }
    rec->files.push_back(f);
  }
  for (const char* required : {kCalibrationYaml, kResidualsCsv}) {
    if (!names.count(required)) {
      const std::string path = (fs::path(directory) / required).string();
      throw util::InputError(fs::exists(path) ? fmt::format("{}: files: '{}' is not listed, so it cannot be verified",
                                                            rec->unit_json_path, required)
                                              : fmt::format("{}: missing: the unit record is incomplete", path));
    }
  }
}

void ReadCameraAndCalibration(JsonSection& r, UnitRecord* rec) {
  JsonSection camera = r.Child("camera");
  rec->camera_pixel_pitch_um = camera.Number("pixel_pitch_um");
  rec->camera_width_px = camera.Integer("width_px");
  rec->camera_height_px = camera.Integer("height_px");
  rec->camera_a_mm = camera.Number("a_mm");

  JsonSection cal = r.Child("calibration");
  rec->calibration_model = cal.NonEmptyString("model");
  rec->calibration_single_view = cal.Bool("single_view");
  rec->calibration_width_px = cal.Integer("image_width_px");
  rec->calibration_height_px = cal.Integer("image_height_px");
  if (rec->calibration_width_px <= 0 || rec->calibration_height_px <= 0) {
    r.Fail("calibration.image_width_px", "the image size must be positive");
  }
  rec->calibration_rms_px = cal.NonNegativeNumber("rms_px");
  rec->corners_used = cal.NonNegativeInteger("corners_used");
  rec->outliers = cal.NonNegativeInteger("outliers");
  const std::size_t n_params = cal.Array("parameters").size();
  if (n_params == 0) r.Fail("calibration.parameters", "must not be empty");
  for (std::size_t i = 0; i < n_params; ++i) {
    JsonSection p = cal.Element("parameters", i);
    rec->parameters.push_back(
        {p.NonEmptyString("name"), p.Number("value"), p.NonNegativeNumber("stddev"), p.Bool("fixed")});
  }
  if (cal.Has("seidel")) {
    JsonSection s = cal.Child("seidel");
    rec->seidel_sigma_per_mm2 = s.Number("sigma_per_mm2");
    rec->seidel_sigma_stddev_per_mm2 = s.Number("sigma_stddev_per_mm2");
    rec->seidel_magnification = s.Number("magnification");
    rec->seidel_focal_mm = s.Number("focal_mm");
  }
  if (cal.Has("distortion_field")) {
    JsonSection df = cal.Child("distortion_field");
    if (df.Has("field_radius_px")) {
      rec->field_radius_px = df.Number("field_radius_px");
      if (*rec->field_radius_px <= 0) df.Fail(df.Key("field_radius_px"), "must be positive");
    }
  }
  const std::size_t n_views = cal.Array("views").size();
  if (n_views == 0) r.Fail("calibration.views", "must not be empty");
  for (std::size_t i = 0; i < n_views; ++i) {
    JsonSection v = cal.Element("views", i);
    rec->views.push_back({v.String("image"), v.NonNegativeNumber("rms_px"), v.NonNegativeInteger("corners")});
  }
}

SphereVerification ReadVerification(JsonSection& r) {
  JsonSection v = r.Child("verification");
  SphereVerification s;
  s.image = v.String("image");
  s.radius_true_mm = v.Number("radius_true_mm");
  if (s.radius_true_mm <= 0) v.Fail(v.Key("radius_true_mm"), "must be positive");
  s.power_true_D = v.Number("power_true_D");
  s.keratometric_index = v.Number("keratometric_index");
  s.uncorrected = ReadStage(v, "uncorrected", kSphereStageKeys);
  s.corrected = ReadStage(v, "corrected", kSphereStageKeys);
  for (auto [key, count] :
       {std::pair{"spots_unassigned", &s.spots_unassigned}, std::pair{"spots_missing", &s.spots_missing}}) {
    if (v.Has(key)) *count = v.NonNegativeInteger(key);
  }
  s.uncertainty = ReadUncertainty(v);
  s.repeatability = ReadRepeatability(v);
  return s;
}

DeviceStageRecord ReadDeviceStages(JsonSection& r) {
  // The device itself comes from device.json (its digest is checked below with every file); unit.json's copy of
  // the parameters is not trusted for anything the report shows.
  JsonSection d = r.Child("device");
  DeviceStageRecord dev;
  JsonSection paper_dev = d.Child("paper_cornea");
  for (const char* stage : kThreeWayStages) dev.paper[stage] = ReadStage(paper_dev, stage, kDeviceStageKeys);
  if (d.Has("held_out_ball")) {
    JsonSection h = d.Child("held_out_ball");
    dev.held_out_radius_true_mm = h.Number("radius_true_mm");
    dev.held_out_power_true_D = h.Number("power_true_D");
    for (const char* stage : kThreeWayStages) dev.held_out[stage] = ReadStage(h, stage, kDeviceStageKeys);
  }
  return dev;
}

// The files, now known to be the ones the record was written with.
void LoadListedFiles(JsonSection& r, const std::string& directory, UnitRecord* rec) {
  rec->calibration_path = (fs::path(directory) / kCalibrationYaml).string();
  rec->calibration = calib::LoadCalibrationFile(rec->calibration_path);
  if (rec->calibration.camera.width_px != rec->calibration_width_px ||
      rec->calibration.camera.height_px != rec->calibration_height_px) {
    r.Fail("calibration.image_width_px", fmt::format("{} x {} px differs from {} ({} x {} px)",
                                                     rec->calibration_width_px, rec->calibration_height_px,
                                                     rec->calibration_path, rec->calibration.camera.width_px,
                                                     rec->calibration.camera.height_px));
  }
  rec->residuals = ReadResiduals((fs::path(directory) / kResidualsCsv).string());
  if (rec->device) {
    const auto listed =
        std::find_if(rec->files.begin(), rec->files.end(), [](const RecordFile& f) { return f.name == "device.json"; });
    if (listed == rec->files.end()) r.Fail("device", "the record has a device stage but no device.json in files");
    rec->device->file = model::LoadDevice((fs::path(directory) / "device.json").string());
  }
  if (rec->verification) {
    const auto listed = std::find_if(rec->files.begin(), rec->files.end(),
                                     [](const RecordFile& f) { return f.name == kSphereSpotsCsv; });
    if (listed != rec->files.end()) {
      rec->verification->detected = model::ReadSpotsCsv((fs::path(directory) / kSphereSpotsCsv).string());
    }
  }
  for (const RecordFile& f : rec->files) {
    const fs::path name(f.name);
    if (name.parent_path() == "maps" && name.extension() == ".png") {
      rec->map_png[name.filename().string()] = util::ReadFile((fs::path(directory) / f.name).string());
    }
  }
}

}  // namespace

UnitRecord ReadUnitRecord(const std::string& directory) {
  UnitRecord rec;
  rec.directory = directory;
  if (!fs::is_directory(directory)) {
    throw util::InputError(fmt::format("{}: not a unit record directory (does not exist)", directory));
  }
  rec.unit_json_path = (fs::path(directory) / kUnitJson).string();
  if (!fs::is_regular_file(rec.unit_json_path)) {
    throw util::InputError(fmt::format("{}: missing: the unit record is incomplete", rec.unit_json_path));
  }
  const std::string text = util::ReadFile(rec.unit_json_path);
  rec.unit_json_sha256 = util::Sha256Hex(text);
  const json root = util::ParseJsonStrict(text, rec.unit_json_path);
  rec.unit_json_content_sha256 = util::Sha256Hex(root.dump());  // nlohmann's objects keep their keys sorted
  JsonSection r(root, rec.unit_json_path, "");

  ReadIdentity(r, &rec);
  ReadSettingsAndInputs(r, &rec);
  ReadAndVerifyFiles(r, directory, &rec);
  ReadCameraAndCalibration(r, &rec);
  if (r.Has("verification")) rec.verification = ReadVerification(r);
  JsonSection paper = r.Child("paper_cornea");
  rec.paper.truth = ReadStage(paper, "truth", kPaperTruthKeys);
  rec.paper.uncorrected = ReadStage(paper, "uncorrected", kPaperStageKeys);
  rec.paper.corrected = ReadStage(paper, "corrected", kPaperStageKeys);
  rec.paper.uncertainty = ReadUncertainty(paper);
  if (r.Has("device")) rec.device = ReadDeviceStages(r);

  // The design and camera the record was computed with (canonical form), for the report's recomputation.
  if (r.Has("configuration")) {
    JsonSection c = r.Child("configuration");
    const std::string origin = rec.unit_json_path + ": configuration";
    rec.config = model::ParseConfig(c.Child("design").raw().dump(), origin + ".design");
    rec.topographer_camera = model::ParseTopographerCamera(c.Child("camera").raw().dump(), origin + ".camera");
  }
  LoadListedFiles(r, directory, &rec);
  return rec;
}

}  // namespace topocal::report

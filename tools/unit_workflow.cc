#include "tools/unit_workflow.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "calib/calibrate.h"
#include "calib/calibration_file.h"
#include "calib/detect.h"
#include "calib/target.h"
#include "model/config.h"
#include "model/io.h"
#include "model/sha256.h"
#include "model/topographer_camera.h"
#include "model/version.h"
#include "pipeline/detection_plane.h"
#include "pipeline/unit_verification.h"
#include "tools/file_glob.h"
#include "tools/map_output.h"

namespace topocal::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kRecordFormat = "topocal-unit-record";
constexpr int kRecordFormatVersion = 1;
constexpr size_t kMaxSerialLength = 64;

// The record's date: SOURCE_DATE_EPOCH when set (the reproducible-builds convention, so that a rerun can be
// compared byte for byte), otherwise now. ISO 8601 UTC.
std::string RecordDateUtc() {
  std::time_t t = std::time(nullptr);
  if (const char* epoch = std::getenv("SOURCE_DATE_EPOCH"); epoch && *epoch) {
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(epoch, &end, 10);
    if (errno != 0 || *end != '\0' || v < 0) {
      throw model::InputError(fmt::format("SOURCE_DATE_EPOCH '{}': not a non-negative integer", epoch));
    }
    t = static_cast<std::time_t>(v);
  }
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

json Numbers(const pipeline::ClinicalNumbers& n) {
  json j = {{"spots", n.spots},
            {"rx_mm", n.rx_mm},
            {"ry_mm", n.ry_mm},
            {"kx", n.kx},
            {"ky", n.ky},
            {"alpha_deg", n.alpha_deg},
            {"radius_mm", n.radius_mm},
            {"central_axial_power_D", n.central_axial_power_D},
            {"pv_tangential_D", n.pv_tangential_D},
            {"pv_axial_D", n.pv_axial_D}};
  if (n.height_pv_um) j["height_pv_um"] = *n.height_pv_um;
  if (n.height_rms_um) j["height_rms_um"] = *n.height_rms_um;
  return j;
}

json Uncertainty(const std::optional<pipeline::ClinicalUncertainty>& u, const pipeline::CheckOptions& o) {
  if (!u) return nullptr;
  json q = json::object();
  for (const auto& [name, v] : u->quantities) q[name] = {{"mean", v.mean}, {"U", v.expanded_k2}};
  return {{"samples", u->samples},         {"seed", o.seed},          {"failed_samples", u->failed_samples},
          {"drawn", u->drawn},             {"correlated", u->correlated}, {"coverage_factor", 2},
          {"quantities", q}};
}

// Largest displacement (um on the detection plane, and px) the calibrated distortion gives a point within
// `radius_mm` of the axis, sampled on a polar grid.
std::pair<double, double> MaxDisplacement(const model::Distortion& d, double radius_mm, double pitch_mm) {
  constexpr int kRings = 20, kMeridians = 72;
  double max_mm = 0;
  for (int i = 1; i <= kRings; ++i) {
    const double r = radius_mm * i / kRings;
    for (int j = 0; j < kMeridians; ++j) {
      const double t = 2 * M_PI * j / kMeridians;
      const Eigen::Vector2d p(r * std::cos(t), r * std::sin(t));
      max_mm = std::max(max_mm, (model::Distort(d, p) - p).norm());
    }
  }
  return {max_mm * 1000.0, max_mm / pitch_mm};
}

// nlohmann writes a NaN or infinity as null, which a reader would take for a missing value: refuse instead,
// naming the key, so that no record carries a number that is not one.
void CheckFinite(const json& j, const std::string& where) {
  if (j.is_object()) {
    for (const auto& [k, v] : j.items()) CheckFinite(v, where.empty() ? k : where + "." + k);
  } else if (j.is_array()) {
    for (size_t i = 0; i < j.size(); ++i) CheckFinite(j[i], fmt::format("{}[{}]", where, i));
  } else if (j.is_number_float() && !std::isfinite(j.get<double>())) {
    throw std::runtime_error(fmt::format("{}: not a finite number", where));
  }
}

// Replaces `out` by the complete directory `staged`: the old record (if any) is moved aside first and removed
// only after the new one is in place, so every moment either the old or the new record is whole.
void CommitDirectory(const fs::path& staged, const fs::path& out) {
  std::error_code ec;
  const fs::path aside = out.string() + fmt::format(".old-{}", ::getpid());
  const bool had_old = fs::exists(out);
  if (had_old) {
    fs::rename(out, aside, ec);
    if (ec) throw model::InputError(fmt::format("{}: cannot replace the existing record: {}", out.string(), ec.message()));
  }
  fs::rename(staged, out, ec);
  if (ec) {
    if (had_old) fs::rename(aside, out, ec);
    throw model::InputError(fmt::format("{}: cannot write the record: {}", out.string(), ec.message()));
  }
  if (had_old) fs::remove_all(aside, ec);
}

// A staging directory that removes itself unless committed.
class Staging {
 public:
  explicit Staging(const fs::path& out) : path_(out.string() + fmt::format(".tmp-{}", ::getpid())) {
    std::error_code ec;
    fs::remove_all(path_, ec);
    fs::create_directories(path_ / "maps", ec);
    if (ec) throw model::InputError(fmt::format("{}: cannot create the record directory: {}", out.string(), ec.message()));
  }
  ~Staging() {
    std::error_code ec;
    if (!committed_) fs::remove_all(path_, ec);
  }
  Staging(const Staging&) = delete;
  Staging& operator=(const Staging&) = delete;
  const fs::path& path() const { return path_; }
  void Commit(const fs::path& out) {
    CommitDirectory(path_, out);
    committed_ = true;
  }

 private:
  fs::path path_;
  bool committed_ = false;
};

}  // namespace

bool IsValidSerial(const std::string& serial) {
  if (serial.empty() || serial.size() > kMaxSerialLength || serial.front() == '.') return false;
  return std::all_of(serial.begin(), serial.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == '-';
  });
}

UnitOutcome CalibrateUnit(const UnitRequest& r, const std::function<void(const std::string&)>& log) {
  // --- Inputs: everything is checked before any work or output.
  if (!IsValidSerial(r.serial)) {
    throw model::InputError(fmt::format("--serial '{}': use 1-{} characters of A-Z a-z 0-9 . _ - (not starting with .)",
                                        r.serial, kMaxSerialLength));
  }
  if (r.out.empty()) throw model::InputError("--out: the record directory is required");
  const auto model_kind = calib::ParseDistortionModel(r.model);
  if (!model_kind) throw model::InputError(fmt::format("--model: '{}' is not seidel or brown5", r.model));
  if (r.reference_sphere.empty() != (r.sphere_radius_mm == 0)) {
    throw model::InputError("--reference-sphere and --sphere-radius-mm go together");
  }
  if (r.uncertainty_samples != 0 && r.uncertainty_samples < 2) {
    throw model::InputError(fmt::format("--uncertainty {}: 0 (none) or at least 2 draws", r.uncertainty_samples));
  }
  if (r.images.empty()) throw model::InputError("--images: no image given");
  for (const auto& f : r.fixed) {
    if (std::find(std::begin(calib::kParameterNames), std::end(calib::kParameterNames), f) ==
        std::end(calib::kParameterNames)) {
      throw model::InputError(fmt::format("--fix: '{}' is not a camera parameter (fx fy cx cy k1 k2 p1 p2 k3 ex ey)", f));
    }
  }
  const fs::path out(r.out);
  if (fs::exists(out) && !fs::exists(out / "unit.json")) {
    throw model::InputError(fmt::format("--out {}: exists and is not a unit record; not overwriting it", r.out));
  }

  const auto config = model::LoadConfig(r.config);
  const auto camera = model::LoadTopographerCamera(r.camera);
  const auto target = calib::LoadTargetDescription(r.target);
  json inputs = json::array();
  const auto add_input = [&](const std::string& role, const std::string& path) {
    inputs.push_back({{"role", role}, {"path", path}, {"sha256", model::Sha256HexOfFile(path)}});
  };
  add_input("config", r.config);
  add_input("camera", r.camera);
  add_input("target", r.target);
  for (const auto& p : r.images) add_input("image", p);
  cv::Mat sphere_image;
  if (!r.reference_sphere.empty()) {
    add_input("reference_sphere", r.reference_sphere);
    sphere_image = cv::imread(r.reference_sphere, cv::IMREAD_UNCHANGED);
    if (sphere_image.empty()) throw model::InputError(fmt::format("{}: not an image OpenCV can read", r.reference_sphere));
    if (sphere_image.cols != camera.width_px || sphere_image.rows != camera.height_px) {
      throw model::InputError(fmt::format("{}: the image is {} x {} px but {} says {} x {} px", r.reference_sphere,
                                          sphere_image.cols, sphere_image.rows, r.camera, camera.width_px,
                                          camera.height_px));
    }
  }

  // --- Calibration.
  std::vector<calib::ViewObservations> views;
  std::vector<std::string> view_paths;
  for (const auto& path : r.images) {
    const cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
    if (image.empty()) throw model::InputError(fmt::format("{}: not an image OpenCV can read", path));
    if (image.cols != camera.width_px || image.rows != camera.height_px) {
      throw model::InputError(fmt::format("{}: the image is {} x {} px but {} says {} x {} px", path, image.cols,
                                          image.rows, r.camera, camera.width_px, camera.height_px));
    }
    const auto found = calib::DetectTargetDetailed(target, image);
    if (!found.view) {
      log(fmt::format("{}: skipping {}: no target found{}", r.serial, path,
                      found.message.empty() ? "" : ": " + found.message));
      continue;
    }
    views.push_back(*found.view);
    views.back().image_path = path;
    view_paths.push_back(path);
  }
  if (views.empty()) throw std::runtime_error(fmt::format("{}: no target found in any image", r.serial));
  calib::CalibrationOptions co;
  co.model = *model_kind;
  co.fit_distortion_centre = r.fit_centre;
  co.fixed = {r.fixed.begin(), r.fixed.end()};
  co.focal_mm = camera.a_mm;
  co.pixel_pitch_um = camera.pixel_pitch_um;
  co.distance_mm = config.topographer.b_mm;
  co.magnification = config.distortion.magnification;
  const bool single_view = r.images.size() == 1;
  const auto result = single_view ? calib::CalibrateSingleView(views[0], co) : calib::CalibrateMultiView(views, co);
  for (const auto& s : result.skipped_views) {
    log(fmt::format("{}: not used {}: {}", r.serial, view_paths[static_cast<size_t>(s.view)], s.reason));
  }
  if (!result.ok()) {
    throw std::runtime_error(
        fmt::format("{}: calibration failed ({}): {}", r.serial, calib::ToString(result.status), result.message));
  }
  const std::string date = RecordDateUtc();
  const calib::CalibrationProvenance provenance{r.target, view_paths, date};
  const std::string cal_text = calib::CalibrationFileText(result, provenance);

  // --- Checks. The unit's calibration as the software will load it (so the checks use what is written).
  pipeline::UnitCalibration unit;
  unit.camera = result.camera;
  unit.covariance.names.assign(std::begin(calib::kParameterNames), std::end(calib::kParameterNames));
  unit.covariance.matrix = result.covariance;
  unit.covariance.full = true;
  const pipeline::CheckOptions check{r.uncertainty_samples, r.seed};
  std::optional<pipeline::SphereVerification> sphere;
  if (!sphere_image.empty()) {
    try {
      sphere = pipeline::VerifyOnReferenceSphere(sphere_image, r.sphere_radius_mm, unit, camera, config, check);
    } catch (const std::invalid_argument& e) {
      throw model::InputError(fmt::format("{}: {}", r.reference_sphere, e.what()));
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(fmt::format("{}: {}: {}", r.serial, r.reference_sphere, e.what()));
    }
  }
  const auto paper = pipeline::SimulateThroughCalibratedCamera(unit, camera, config, check);
  std::string why;
  const auto distortion = pipeline::DistortionOnDetectionPlane(result.camera, camera, &why);
  if (!distortion) throw std::runtime_error(fmt::format("{}: {}", r.serial, why));
  // The field the spot pattern covers on the detection plane: the outer ring's image radius, with a margin.
  double field_radius_mm = 0;
  {
    const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
    const auto ideal = model::SynthesizeImage(model::Biconic{config.cornea}, model::Topographer{config.topographer},
                                              design.targets);
    for (const auto& s : ideal.spots) field_radius_mm = std::max(field_radius_mm, s.position_mm.norm());
  }
  const auto [max_um, max_px] = MaxDisplacement(*distortion, field_radius_mm, camera.PitchMm());

  // --- The record, staged and committed whole.
  Staging staging(out);
  const fs::path dir = staging.path();
  model::WriteFileAtomic((dir / "calibration.yaml").string(), cal_text);
  std::string residuals = "view,image,corner_id,x_px,y_px,dx_px,dy_px,outlier\n";
  for (const auto& c : result.residuals) {
    residuals += fmt::format("{},{},{},{:.6f},{:.6f},{:.6f},{:.6f},{}\n", c.view,
                             view_paths[static_cast<size_t>(c.view)], c.corner_id, c.observed_px.x(),
                             c.observed_px.y(), c.residual_px.x(), c.residual_px.y(), c.outlier ? 1 : 0);
  }
  model::WriteFileAtomic((dir / "residuals.csv").string(), residuals);
  const std::string maps = (dir / "maps").string();
  // The PNGs go in the record, at half the default size (~0.15 MB each; the report embeds them all); the numbers
  // are in unit.json (CSV grids would be ~0.6 MB each).
  constexpr bool kMapCsv = false;
  constexpr int kMapSizePx = 400;
  if (sphere) {
    const model::Config sphere_config = pipeline::WithSphere(config, r.sphere_radius_mm);
    WriteAnalysisMaps(maps, "sphere_uncorrected_", " - reference sphere, uncorrected", sphere->uncorrected.analysis,
                      &sphere_config.cornea, kMapCsv, kMapSizePx);
    WriteAnalysisMaps(maps, "sphere_corrected_", " - reference sphere, corrected", sphere->corrected.analysis,
                      &sphere_config.cornea, kMapCsv, kMapSizePx);
  }
  WriteAnalysisMaps(maps, "paper_uncorrected_", " - paper cornea, uncorrected", paper.uncorrected.analysis,
                    &config.cornea, kMapCsv, kMapSizePx);
  WriteAnalysisMaps(maps, "paper_corrected_", " - paper cornea, corrected", paper.corrected.analysis, &config.cornea,
                    kMapCsv, kMapSizePx);

  json files = json::array();
  std::vector<std::string> names;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) names.push_back(fs::relative(e.path(), dir).generic_string());
  }
  std::sort(names.begin(), names.end());
  for (const auto& n : names) files.push_back({{"name", n}, {"sha256", model::Sha256HexOfFile((dir / n).string())}});

  json cal;
  cal["model"] = std::string(calib::ToString(result.model));
  cal["single_view"] = result.single_view;
  cal["image_width_px"] = result.camera.width_px;
  cal["image_height_px"] = result.camera.height_px;
  cal["rms_px"] = result.rms_px;
  cal["corners_used"] = result.corners_used;
  cal["outliers"] = result.outliers.size();
  cal["parameters"] = json::array();
  for (const auto& p : result.parameters) {
    cal["parameters"].push_back({{"name", p.name}, {"value", p.value}, {"stddev", p.stddev}, {"fixed", p.fixed}});
  }
  json cov_names = json::array(), cov_rows = json::array();
  std::vector<int> free_index;
  for (int i = 0; i < calib::kNumCameraParameters; ++i) {
    if (!result.parameters[static_cast<size_t>(i)].fixed) free_index.push_back(i);
  }
  for (const int i : free_index) {
    cov_names.push_back(result.parameters[static_cast<size_t>(i)].name);
    json row = json::array();
    for (const int j : free_index) row.push_back(result.covariance(i, j));
    cov_rows.push_back(row);
  }
  cal["covariance"] = {{"names", cov_names}, {"matrix", cov_rows}};
  if (result.seidel) {
    cal["seidel"] = {{"sigma_per_mm2", result.seidel->sigma_per_mm2},
                     {"sigma_stddev_per_mm2", result.seidel->sigma_stddev_per_mm2},
                     {"magnification", result.seidel->magnification},
                     {"focal_mm", result.seidel->focal_mm}};
  }
  cal["views"] = json::array();
  for (size_t v = 0; v < result.views_used.size(); ++v) {
    const auto idx = static_cast<size_t>(result.views_used[v]);
    int corners = 0;
    for (const auto& c : result.residuals) corners += (static_cast<size_t>(c.view) == idx && !c.outlier) ? 1 : 0;
    cal["views"].push_back({{"image", view_paths[idx]}, {"rms_px", result.per_view_rms_px[v]}, {"corners", corners}});
  }
  cal["distortion_field"] = {{"max_displacement_um", max_um},
                             {"max_displacement_px", max_px},
                             {"field_radius_mm", field_radius_mm},
                             {"field_radius_px", field_radius_mm / camera.PitchMm()}};

  json record;
  record["format"] = kRecordFormat;
  record["format_version"] = kRecordFormatVersion;
  record["tool_version"] = kVersion;
  record["serial"] = r.serial;
  record["created_utc"] = date;
  record["settings"] = {{"model", r.model},
                        {"single_view", single_view},
                        {"fit_centre", r.fit_centre},
                        {"fixed", r.fixed},
                        {"sphere_radius_mm", r.sphere_radius_mm},
                        {"uncertainty_samples", r.uncertainty_samples},
                        {"seed", r.seed}};
  record["inputs"] = inputs;
  record["files"] = files;
  record["camera"] = {{"pixel_pitch_um", camera.pixel_pitch_um},
                      {"width_px", camera.width_px},
                      {"height_px", camera.height_px},
                      {"a_mm", camera.a_mm},
                      {"principal_point_px", {camera.principal_point_px.x(), camera.principal_point_px.y()}},
                      {"rotated_180", camera.rotated_180}};
  record["calibration"] = cal;
  if (sphere) {
    json v = {{"image", r.reference_sphere},
              {"radius_true_mm", sphere->radius_true_mm},
              {"power_true_D", sphere->power_true_D},
              {"keratometric_index", topo::kKeratometricIndex},
              {"central_zone_diameter_mm", 2 * pipeline::kCentralPowerRadiusMm},
              {"spots_indexed", sphere->spots_indexed},
              {"spots_unassigned", sphere->spots_unassigned},
              {"spots_missing", sphere->spots_missing},
              {"undistort_failures", sphere->undistort_failures}};
    for (const auto* stage : {&sphere->uncorrected, &sphere->corrected}) {
      json n = Numbers(stage->numbers);
      n["spots_indexed"] = sphere->spots_indexed;  // both stages use the same detected and indexed spots
      n["radius_error_mm"] = sphere->RadiusErrorMm(*stage);
      n["power_error_D"] = sphere->PowerErrorD(*stage);
      v[stage == &sphere->uncorrected ? "uncorrected" : "corrected"] = n;
    }
    v["uncertainty"] = Uncertainty(sphere->uncertainty, check);
    record["verification"] = v;
  }
  record["paper_cornea"] = {{"truth",
                             {{"rx_mm", paper.truth.rx_mm},
                              {"ry_mm", paper.truth.ry_mm},
                              {"kx", paper.truth.kx},
                              {"ky", paper.truth.ky},
                              {"alpha_deg", paper.truth.alpha_deg}}},
                            {"max_displacement_um", paper.max_displacement_um},
                            {"uncorrected", Numbers(paper.uncorrected.numbers)},
                            {"corrected", Numbers(paper.corrected.numbers)},
                            {"uncertainty", Uncertainty(paper.uncertainty, check)}};
  try {
    CheckFinite(record, "");
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: the result is not usable: {}", r.serial, e.what()));
  }
  const std::string text = record.dump(2) + "\n";
  model::WriteFileAtomic((dir / "unit.json").string(), text);
  staging.Commit(out);

  UnitOutcome o;
  o.serial = r.serial;
  o.out = r.out;
  o.summary.push_back(fmt::format("{}: {} {} calibration, {} view(s), {} corners, rms {:.4f} px{}", r.serial,
                                  calib::ToString(result.model), single_view ? "single-view" : "multi-view",
                                  result.views_used.size(), result.corners_used, result.rms_px,
                                  result.seidel ? fmt::format(", sigma {:.6g} +- {:.2g} mm^-2 (k=1)",
                                                              result.seidel->sigma_per_mm2,
                                                              result.seidel->sigma_stddev_per_mm2)
                                                : std::string()));
  o.summary.push_back(fmt::format("  distortion: up to {:.2f} um ({:.1f} px) over the spot field", max_um, max_px));
  if (sphere) {
    const auto& s = *sphere;
    o.summary.push_back(fmt::format(
        "  reference sphere R {} mm: radius error {:+.4f} -> {:+.4f} mm, central power error {:+.3f} -> {:+.3f} D",
        s.radius_true_mm, s.RadiusErrorMm(s.uncorrected), s.RadiusErrorMm(s.corrected), s.PowerErrorD(s.uncorrected),
        s.PowerErrorD(s.corrected)));
  }
  const auto u = [&](const char* q) {
    if (!paper.uncertainty || !paper.uncertainty->quantities.count(q)) return std::string();
    return fmt::format(" +- {:.2g}", paper.uncertainty->quantities.at(q).expanded_k2);
  };
  o.summary.push_back(fmt::format("  paper cornea (simulated): kx {:.4f} -> {:.4f}{}, ky {:.4f} -> {:.4f}{} (truth {}, {})",
                                  paper.uncorrected.numbers.kx, paper.corrected.numbers.kx, u("kx"),
                                  paper.uncorrected.numbers.ky, paper.corrected.numbers.ky, u("ky"), paper.truth.kx,
                                  paper.truth.ky));
  o.summary.push_back(fmt::format("  -> {}", r.out));
  return o;
}

UnitRequest ReadUnitInputs(const std::string& path, const UnitRequest& defaults) {
  const std::string text = model::ReadFile(path);
  json j;
  try {
    j = json::parse(text);
  } catch (const json::parse_error& e) {
    throw model::InputError(fmt::format("{}: not valid JSON: {}", path, e.what()));
  }
  if (!j.is_object()) throw model::InputError(fmt::format("{}: expected a JSON object", path));
  static const std::vector<std::string> kKeys = {"serial", "target",           "images",      "reference_sphere",
                                                 "sphere_radius_mm", "model",  "fit_centre",  "fix", "config",
                                                 "camera",  "uncertainty_samples", "seed"};
  for (const auto& [key, value] : j.items()) {
    if (std::find(kKeys.begin(), kKeys.end(), key) == kKeys.end()) {
      throw model::InputError(fmt::format("{}: {}: unknown key", path, key));
    }
  }
  const fs::path base = fs::path(path).parent_path();
  const auto relative = [&](const std::string& p) { return fs::path(p).is_absolute() ? p : (base / p).string(); };
  const auto str = [&](const char* key, bool required) -> std::optional<std::string> {
    if (!j.contains(key)) {
      if (required) throw model::InputError(fmt::format("{}: {}: missing", path, key));
      return std::nullopt;
    }
    if (!j[key].is_string() || j[key].get<std::string>().empty()) {
      throw model::InputError(fmt::format("{}: {}: expected a non-empty string", path, key));
    }
    return j[key].get<std::string>();
  };
  UnitRequest r = defaults;
  r.serial = *str("serial", true);
  r.target = relative(*str("target", true));
  r.images = Glob(relative(*str("images", true)), fmt::format("{}: images", path));
  if (const auto s = str("reference_sphere", false)) r.reference_sphere = relative(*s);
  if (j.contains("sphere_radius_mm")) {
    if (!j["sphere_radius_mm"].is_number() || !(j["sphere_radius_mm"].get<double>() > 0)) {
      throw model::InputError(fmt::format("{}: sphere_radius_mm: expected a positive number", path));
    }
    r.sphere_radius_mm = j["sphere_radius_mm"].get<double>();
  }
  if (const auto s = str("model", false)) r.model = *s;
  if (const auto s = str("config", false)) r.config = relative(*s);
  if (const auto s = str("camera", false)) r.camera = relative(*s);
  if (j.contains("fit_centre")) {
    if (!j["fit_centre"].is_boolean()) throw model::InputError(fmt::format("{}: fit_centre: expected true or false", path));
    r.fit_centre = j["fit_centre"].get<bool>();
  }
  if (j.contains("fix")) {
    if (!j["fix"].is_array()) throw model::InputError(fmt::format("{}: fix: expected a list of parameter names", path));
    r.fixed.clear();
    for (const auto& f : j["fix"]) {
      if (!f.is_string()) throw model::InputError(fmt::format("{}: fix: expected a list of parameter names", path));
      r.fixed.push_back(f.get<std::string>());
    }
  }
  if (j.contains("uncertainty_samples")) {
    if (!j["uncertainty_samples"].is_number_integer()) {
      throw model::InputError(fmt::format("{}: uncertainty_samples: expected an integer", path));
    }
    r.uncertainty_samples = j["uncertainty_samples"].get<int>();
  }
  if (j.contains("seed")) {
    if (!j["seed"].is_number_unsigned()) throw model::InputError(fmt::format("{}: seed: expected a non-negative integer", path));
    r.seed = j["seed"].get<unsigned>();
  }
  return r;
}

}  // namespace topocal::tools

#include "report/unit_record_writer.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "calib/calibration_file.h"
#include "calib/parameter_range.h"
#include "model/config.h"
#include "model/device.h"
#include "model/spots_csv.h"
#include "model/topographer_camera.h"
#include "pipeline/map_output.h"
#include "pipeline/uncertainty.h"
#include "pipeline/unit_workflow.h"
#include "report/unit_record_reader.h"
#include "topo/biconic_fit.h"
#include "topo/power_map.h"
#include "util/io.h"
#include "util/json_section.h"
#include "util/build_info.h"
#include "util/sha256.h"
#include "util/version.h"

namespace topocal::report {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Every file under `dir` but unit.json, sorted, with its digest.
json FileDigests(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    std::string name = fs::relative(e.path(), dir).generic_string();
    if (name != "unit.json") names.push_back(std::move(name));
  }
  std::sort(names.begin(), names.end());
  json files = json::array();
  for (const auto& n : names) files.push_back({{"name", n}, {"sha256", util::Sha256HexOfFile((dir / n).string())}});
  return files;
}

// The record set aside, into its unit's history (pipeline::RecordHistoryDir), under its creation time.
void KeepInHistory(const fs::path& aside, const fs::path& out) {
  std::string created = "undated";
  try {
    std::ifstream in(aside / "unit.json");
    created = json::parse(in).at("created_utc").get<std::string>();
  } catch (const std::exception&) {
  }
  for (char& c : created) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-') c = '-';  // 2026-12-03T18-40-00Z
  }
  const fs::path history = pipeline::RecordHistoryDir(out);
  std::error_code ec;
  fs::create_directories(history, ec);
  fs::path kept = history / created;
  for (int n = 2; fs::exists(kept, ec); ++n) kept = history / fmt::format("{}-{}", created, n);
  fs::rename(aside, kept, ec);
  if (ec) {
    throw util::InputError(fmt::format("{}: the new record is in place but the old one could not be kept in {}: {} "
                                       "(it is at {})",
                                       out.string(), history.string(), ec.message(), aside.string()));
  }
}

// Replaces `out` by the complete directory `staged`: the old record (if any) is moved aside first and, only after
// the new one is in place, kept in the history (keep_history) — refused otherwise — so every moment either the old
// or the new record is whole.
void CommitDirectory(const fs::path& staged, const fs::path& out, bool keep_history) {
  const util::DeferSignalCleanup defer;  // a signal between the two renames would lose both records
  std::error_code ec;
  const fs::path aside = out.string() + fmt::format(".old-{}", ::getpid());
  const bool had_old = fs::exists(out);
  if (had_old && !keep_history) {
    throw util::InputError(fmt::format("{}: a record is already there; --force keeps it under {} and writes this one",
                                       out.string(), pipeline::RecordHistoryDir(out).string()));
  }
  if (had_old) {
    fs::rename(out, aside, ec);
    if (ec)
      throw util::InputError(fmt::format("{}: cannot replace the existing record: {}", out.string(), ec.message()));
  }
  fs::rename(staged, out, ec);
  if (ec) {
    if (had_old) fs::rename(aside, out, ec);
    throw util::InputError(fmt::format("{}: cannot write the record: {}", out.string(), ec.message()));
  }
  if (had_old) KeepInHistory(aside, out);
}

}  // namespace

namespace {
// "units/SN/" and "units/SN" are the same record: without the trailing separator, so that the staging directory
// ("units/SN.tmp-PID-TOKEN") is a sibling of the record and not inside it (which made every such run fail).
fs::path RecordPath(fs::path out) {
  out = out.lexically_normal();
  if (out.filename().empty() && out.has_parent_path()) out = out.parent_path();
  return out;
}
}  // namespace

namespace {

// A staging folder (NAME.tmp-PID[-TOKEN]) or a record set aside (NAME.old-PID) that a run killed by SIGKILL left
// beside the record NAME. Only the writer holding the record's lock may judge them: any other writer would hold it.
bool IsLeftoverOf(const std::string& entry, const std::string& record) {
  for (const char* kind : {".tmp-", ".old-"}) {
    const std::string prefix = record + kind;
    if (entry.rfind(prefix, 0) == 0 && entry.size() > prefix.size() &&
        std::isdigit(static_cast<unsigned char>(entry[prefix.size()]))) {
      return true;
    }
  }
  return false;
}

// Removes what killed runs left beside `out`; a record set aside (NAME.old-PID) whose replacement never arrived is
// put back instead (the run died between the two renames of CommitDirectory).
void CleanLeftovers(const fs::path& out) {
  std::error_code ec;
  const fs::path parent = out.has_parent_path() ? out.parent_path() : fs::path(".");
  const std::string name = out.filename().string();
  std::vector<fs::path> leftovers;
  for (const auto& e : fs::directory_iterator(parent, ec)) {
    if (IsLeftoverOf(e.path().filename().string(), name)) leftovers.push_back(e.path());
  }
  std::sort(leftovers.begin(), leftovers.end());
  for (const auto& p : leftovers) {
    const bool set_aside = p.filename().string().rfind(name + ".old-", 0) == 0;
    if (set_aside && !fs::exists(out, ec) && !fs::is_symlink(p, ec)) {
      fs::rename(p, out, ec);
    } else {
      fs::remove_all(p, ec);  // a link is removed, not followed
    }
  }
}

fs::path LockPath(const fs::path& out) {
  const fs::path parent = out.has_parent_path() ? out.parent_path() : fs::path(".");
  return parent / fmt::format(".{}.lock", out.filename().string());
}

// The record's lock: flock on a hidden file beside it, held for the writer's life and released by the kernel
// however the process ends. The writer removes the file when it is done (and a signal's cleanup does), so nothing
// is left behind; a taker that opened the file before its removal finds, after locking, that the path no longer
// names its file, and starts again (the usual protocol for lock files that are removed).
int LockRecord(const fs::path& out) {
  const fs::path lock = LockPath(out);
  for (int attempt = 0; attempt < 16; ++attempt) {
    const int fd = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0666);
    if (fd < 0) {
      throw util::InputError(fmt::format("{}: cannot create the record's lock {}: {}", out.string(), lock.string(),
                                         std::strerror(errno)));
    }
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int e = errno;
      ::close(fd);
      if (e == EWOULDBLOCK) {
        throw util::InputError(fmt::format(
            "{}: another topocal run is writing this record now; nothing written (run again when it is done)",
            out.string()));
      }
      throw util::InputError(fmt::format("{}: cannot lock the record: {}", out.string(), std::strerror(e)));
    }
    struct stat held {}, named {};
    if (::fstat(fd, &held) == 0 && ::lstat(lock.c_str(), &named) == 0 && held.st_dev == named.st_dev &&
        held.st_ino == named.st_ino) {
      return fd;
    }
    ::close(fd);  // removed (or replaced) between our open and our lock: take the new one
  }
  throw util::InputError(fmt::format("{}: cannot lock the record: its lock file keeps changing", out.string()));
}

}  // namespace

bool IsRecordLeftover(const fs::path& path) {
  const std::string name = RecordPath(path).filename().string();
  for (const char* kind : {".tmp-", ".old-"}) {
    const size_t at = name.rfind(kind);
    if (at != std::string::npos && at > 0 && IsLeftoverOf(name, name.substr(0, at))) return true;
  }
  return false;
}

UnitRecordWriter::UnitRecordWriter(fs::path out, bool keep_history)
    : out_(RecordPath(std::move(out))), keep_history_(keep_history) {
  std::error_code ec;
  const fs::path parent = out_.has_parent_path() ? out_.parent_path() : fs::path(".");
  fs::create_directories(parent, ec);
  if (ec) throw util::InputError(fmt::format("{}: cannot create {}: {}", out_.string(), parent.string(), ec.message()));
  lock_fd_ = LockRecord(out_);
  util::RegisterCleanupPath(LockPath(out_).string());
  CleanLeftovers(out_);
  // An unpredictable name, created exclusively: a link planted there cannot redirect the record.
  staging_ = out_.string() + fmt::format(".tmp-{}-{}", ::getpid(), util::UnpredictableToken());
  util::RegisterCleanupPath(staging_.string());  // SIGINT/SIGTERM remove it
  // A constructor that throws runs no destructor: whatever it made is undone here, the lock released.
  const auto fail = [&](int e, bool staging_is_ours) {
    if (staging_is_ours) fs::remove_all(staging_, ec);
    util::UnregisterCleanupPath(staging_.string());
    Unlock();
    return util::InputError(
        fmt::format("{}: cannot create the record directory: {}", out_.string(), std::strerror(e)));
  };
  if (::mkdir(staging_.c_str(), 0777) != 0) throw fail(errno, false);
  if (::mkdir((staging_ / "maps").c_str(), 0777) != 0) throw fail(errno, true);
}

UnitRecordWriter::~UnitRecordWriter() {
  std::error_code ec;
  if (!committed_ && !staging_.empty()) fs::remove_all(staging_, ec);
  util::UnregisterCleanupPath(staging_.string());
  Unlock();
}

void UnitRecordWriter::Unlock() {
  if (lock_fd_ < 0) return;
  const std::string lock = LockPath(out_).string();
  ::unlink(lock.c_str());  // while still held: the next taker re-checks the path after locking
  util::UnregisterCleanupPath(lock);
  ::close(lock_fd_);
  lock_fd_ = -1;
}

void UnitRecordWriter::WriteFile(const std::string& name, std::string_view bytes) const {
  const fs::path path = staging_ / name;
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (ec)
    throw util::InputError(fmt::format("{}: cannot create directory: {}", path.parent_path().string(), ec.message()));
  util::WriteFileAtomic(path.string(), bytes);
}

void UnitRecordWriter::Commit(json body) {
  body["format"] = kUnitRecordFormat;
  body["format_version"] = kUnitRecordFormatVersion;
  body["tool_version"] = kVersion;
  body["tool_commit"] = BuildCommit();  // the exact code (util/build_info.h)
  body["files"] = FileDigests(staging_);
  util::WriteFileAtomic((staging_ / "unit.json").string(), util::JsonFileText(body));
  CommitDirectory(staging_, out_, keep_history_);
  committed_ = true;
}

namespace {

// unit.json's body from the computed unit: the one place that spells the record's keys on the writing side
// (their reader is report/unit_record_reader.cc; docs/unit-record.md is the schema).
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
            {"pv_axial_D", n.pv_axial_D},
            {"adequacy_ratio", n.adequacy_ratio},
            {"structured_residual_ratio", n.structured_residual_ratio}};
  if (n.height_pv_um) j["height_pv_um"] = *n.height_pv_um;
  if (n.height_rms_um) j["height_rms_um"] = *n.height_rms_um;
  return j;
}

json Uncertainty(const std::optional<pipeline::ClinicalUncertainty>& u, const pipeline::CheckOptions& o) {
  if (!u) return nullptr;
  json q = json::object();
  for (const auto& [name, v] : u->quantities) q[name] = {{"mean", v.mean}, {"U", v.expanded_k2}};
  return {{"method", u->linear ? "linear" : "monte-carlo"},
          {"samples", u->samples},         {"seed", o.seed},          {"failed_samples", u->failed_samples},
          {"undistort_failures", u->undistort_failures},
          {"draws_with_undistort_failures", u->draws_with_undistort_failures},
          {"drawn", u->drawn},             {"correlated", u->correlated}, {"coverage_factor", 2},
          {"quantities", q}};
}

json ThreeWayJson(const pipeline::ThreeWay& t) {
  return {{"uncorrected", Numbers(t.uncorrected.numbers)},
          {"lens_only", Numbers(t.lens_only.numbers)},
          {"device", Numbers(t.device.numbers)}};
}

json DeviceJson(const pipeline::UnitDeviceStage& d) {
  json j = pipeline::DeviceCalibrationJson(d.calibration);
  j["file"] = "device.json";
  if (d.held_out) {
    const auto& h = *d.held_out;
    j["held_out_ball"] = ThreeWayJson(h.stages);
    j["held_out_ball"]["radius_true_mm"] = h.radius_true_mm;
    j["held_out_ball"]["power_true_D"] = h.power_true_D;
    j["held_out_ball"]["spots_indexed"] = h.spots_indexed;
  }
  j["paper_cornea"] = ThreeWayJson(d.paper);
  return j;
}

json CalibrationJson(const pipeline::UnitCameraCalibration& c, const pipeline::DistortionField& field,
                     const model::TopographerCamera& camera) {
  const auto& result = c.result;
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
  // Parameters the views did not determine, recorded only when the unit was calibrated with --allow-undetermined
  // (otherwise refused): their values are not to be used.
  cal["undetermined"] = json::array();
  for (const auto& u : calib::UndeterminedParameters(result)) cal["undetermined"].push_back(u.name);
  // The covariance of the free parameters only (the calibration file holds the full one).
  std::vector<int> free_index;
  for (int i = 0; i < static_cast<int>(result.parameters.size()); ++i) {
    if (!result.parameters[static_cast<size_t>(i)].fixed) free_index.push_back(i);
  }
  json names = json::array(), rows = json::array();
  for (const int i : free_index) {
    names.push_back(result.parameters[static_cast<size_t>(i)].name);
    json row = json::array();
    for (const int j : free_index) row.push_back(result.covariance(i, j));
    rows.push_back(row);
  }
  cal["covariance"] = {{"names", names}, {"matrix", rows}};
  if (result.seidel) {
    cal["seidel"] = {{"sigma_per_mm2", result.seidel->sigma_per_mm2},
                     {"sigma_stddev_per_mm2", result.seidel->sigma_stddev_per_mm2},
                     {"magnification", result.seidel->magnification},
                     {"focal_mm", result.seidel->focal_mm}};
  }
  cal["views"] = json::array();
  for (size_t v = 0; v < result.views_used.size(); ++v) {
    const auto idx = result.views_used[v];
    const auto corners = std::count_if(result.residuals.begin(), result.residuals.end(),
                                       [&](const auto& r) { return r.view == idx && !r.outlier; });
    cal["views"].push_back({{"image", c.view_paths[static_cast<size_t>(idx)]},
                            {"rms_px", result.per_view_rms_px[v]},
                            {"corners", corners}});
  }
  cal["distortion_field"] = {{"max_displacement_um", field.max_um},
                             {"max_displacement_px", field.max_px},
                             {"field_radius_mm", field.field_radius_mm},
                             {"field_radius_px", field.field_radius_mm / camera.PitchMm()}};
  return cal;
}

std::string ResidualsCsv(const pipeline::UnitCameraCalibration& c) {
  std::string csv = "view,image,corner_id,x_px,y_px,dx_px,dy_px,outlier\n";
  for (const auto& r : c.result.residuals) {
    csv += fmt::format("{},{},{},{:.6f},{:.6f},{:.6f},{:.6f},{}\n", r.view, c.view_paths[static_cast<size_t>(r.view)],
                       r.corner_id, r.observed_px.x(), r.observed_px.y(), r.residual_px.x(), r.residual_px.y(),
                       r.outlier ? 1 : 0);
  }
  return csv;
}

void WriteRecordMaps(const std::string& dir, const std::optional<pipeline::SphereVerification>& sphere,
                     const pipeline::SimulatedCornea& paper, const model::Config& config, int jobs, bool csv) {
  // The PNGs go in the record at half the default size (the report embeds them all); the numbers are in unit.json,
  // and the CSV grids behind the pictures (~3 MB each) only when asked for.
  constexpr int kMapSizePx = 400;
  // Each case's before/after pair is one set: both stages on the same scales, so that they compare by eye.
  pipeline::MapSetOptions o;
  o.csv = csv;
  o.size_px = kMapSizePx;
  o.jobs = jobs;  // the unit's threads (its draws are done by now); the same files on any number
  if (sphere) {
    const auto truth = pipeline::WithSphere(config, sphere->radius_true_mm).cornea;
    pipeline::WriteAnalysisMapSet(dir,
                        {{"sphere_uncorrected_", " - reference sphere, uncorrected", &sphere->uncorrected.analysis, &truth, {}},
                         {"sphere_corrected_", " - reference sphere, corrected", &sphere->corrected.analysis, &truth, {}}},
                        o);
  }
  pipeline::WriteAnalysisMapSet(dir,
                      {{"paper_uncorrected_", " - paper cornea, uncorrected", &paper.uncorrected.analysis, &config.cornea, {}},
                       {"paper_corrected_", " - paper cornea, corrected", &paper.corrected.analysis, &config.cornea, {}}},
                      o);
}

}  // namespace

json VerificationJson(const pipeline::SphereVerification& s, const std::string& image,
                      const pipeline::CheckOptions& check) {
  json v = {{"image", image},
            {"radius_true_mm", s.radius_true_mm},
            {"power_true_D", s.power_true_D},
            {"keratometric_index", topo::kKeratometricIndex},
            {"central_zone_diameter_mm", 2 * pipeline::kCentralPowerRadiusMm},
            {"spots_indexed", s.spots_indexed},
            {"spots_unassigned", s.spots_unassigned},
            {"spots_missing", s.spots_missing},
            {"undistort_failures", s.undistort_failures},
            // "sphere": centre and radius fitted; kx, ky, alpha_deg are 0 by construction (docs/unit-record.md)
            {"surface_fit", topo::BiconicFitModeName(s.corrected.analysis.surface_fit.mode)}};
  for (const auto& [name, stage] : {std::pair{"uncorrected", &s.uncorrected}, std::pair{"corrected", &s.corrected}}) {
    json n = Numbers(stage->numbers);
    n["spots_indexed"] = s.spots_indexed;  // both stages use the same detected and indexed spots
    n["radius_error_mm"] = s.RadiusErrorMm(*stage);
    n["power_error_D"] = s.PowerErrorD(*stage);
    v[name] = n;
  }
  v["uncertainty"] = Uncertainty(s.uncertainty, check);
  return v;
}

json PaperCorneaJson(const pipeline::SimulatedCornea& paper, const pipeline::CheckOptions& check) {
  const auto& t = paper.truth;
  return {{"truth", {{"rx_mm", t.rx_mm}, {"ry_mm", t.ry_mm}, {"kx", t.kx}, {"ky", t.ky}, {"alpha_deg", t.alpha_deg}}},
          {"max_displacement_um", paper.max_displacement_um},
          {"uncorrected", Numbers(paper.uncorrected.numbers)},
          {"corrected", Numbers(paper.corrected.numbers)},
          {"uncertainty", Uncertainty(paper.uncertainty, check)}};
}

void WriteUnitRecord(const pipeline::UnitResult& u) {
  const auto& r = u.request;
  const auto& c = u.calibration;
  // The record, staged and committed whole.
  UnitRecordWriter writer(r.out, r.keep_history);
  const fs::path& dir = writer.staging_dir();
  util::WriteFileAtomic((dir / "calibration.yaml").string(),
                        calib::CalibrationFileText(c.result, {r.target, c.view_paths, u.created_utc}));
  util::WriteFileAtomic((dir / "residuals.csv").string(), ResidualsCsv(c));
  WriteRecordMaps((dir / "maps").string(), u.sphere, u.paper, u.config, r.jobs, r.map_csv);
  if (u.sphere) {
    // The sphere's identified spots as the camera saw them: the report recomputes the check from them
    // (report/record_check.h). Shortest round-trip decimals, so the recomputation starts from the same doubles.
    std::vector<model::ImageSpot> spots;
    spots.reserve(u.sphere->detected.size());
    for (const auto& d : u.sphere->detected) spots.push_back({d.id, d.position_mm, Eigen::Vector3d::Zero()});
    util::WriteFileAtomic((dir / kSphereSpotsCsv).string(), model::SpotsCsv(spots));
  }
  if (u.device) {
    util::WriteFileAtomic(
        (dir / "device.json").string(),
        model::DeviceToJson(u.device->calibration.fit.device, pipeline::DeviceCalibrationJson(u.device->calibration)));
  }

  json record;
  record["serial"] = r.serial;
  record["created_utc"] = u.created_utc;
  record["settings"] = {{"model", r.model},
                        {"single_view", c.single_view},
                        {"fit_centre", r.fit_centre},
                        {"fixed", r.fixed},
                        {"fixed_aspect_ratio", r.fixed_aspect_ratio},
                        {"sphere_radius_mm", r.sphere_radius_mm},
                        {"ball_radii_mm", r.ball_radii_mm},
                        {"uncertainty", r.uncertainty.MethodName()},
                        {"uncertainty_samples", r.uncertainty.draws},
                        {"seed", r.seed}};
  record["inputs"] = json::array();
  for (const auto& in : u.inputs) record["inputs"].push_back({{"role", in.role}, {"path", in.path}, {"sha256", in.sha256}});
  // The design and camera as they were read (canonical form), so that the record says what it was computed with
  // even after the files change; the digests above say whether they still match.
  record["configuration"] = {{"design", json::parse(model::ConfigToJson(u.config))},
                             {"camera", json::parse(model::TopographerCameraToJson(u.camera))}};
  record["camera"] = model::CameraToJson(u.camera);
  record["calibration"] = CalibrationJson(c, u.field, u.camera);
  if (u.sphere) record["verification"] = VerificationJson(*u.sphere, r.reference_sphere, u.check);
  if (u.sphere_repeats) {
    // Read back by ReadUnitRecord: their sample standard deviations are the budget's repeatability terms.
    record["verification"]["repeatability"] = {{"radius_mm", u.sphere_repeats->radius_mm},
                                               {"central_axial_power_D", u.sphere_repeats->central_axial_power_D}};
  }
  record["paper_cornea"] = PaperCorneaJson(u.paper, u.check);
  if (u.device) record["device"] = DeviceJson(*u.device);
  try {
    util::RequireFiniteNumbers(record);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: the result is not usable: {}", r.serial, e.what()));
  }
  writer.Commit(std::move(record));  // adds format, versions and the files' digests
}

}  // namespace topocal::report

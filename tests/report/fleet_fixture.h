#pragma once
// A generated production line for the fleet tests: unit records with seeded, varied numbers, written through the
// project's record writer (report/unit_record_writer.h) so that their digests are valid. The calibration is one real
// single-view Seidel calibration (record_fixture.h) whose k1 is scaled per unit; the reference-sphere and paper-cornea
// numbers are drawn around what a corrected unit measures. Free of GoogleTest: bench/fleet_generate.cc writes the
// line at scale (GenerateFleet) with it.
#include <cmath>
#include <ctime>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "calib/calibration_file.h"
#include "report/unit_record_writer.h"
#include "tests/report/record_body.h"

namespace topocal::report::testing {

struct LineUnit {
  std::string serial, created_utc;
  double sigma_scale = 1;        // k1 and sigma x this
  double radius_error_mm = 0;    // reference sphere, corrected
  double rms_px = 0.03;
  double kx_error = 0, ky_error = 0;
};

// Scatter of the generated line (1 sigma), the size a corrected unit shows (docs/closed-loop.md: k within 4e-4).
inline constexpr double kLineRadiusScatterMm = 0.002, kLineRmsScatterPx = 0.004, kLineConicScatter = 3e-4,
                        kLineSigmaScatter = 0.01;

// `n` units, one an hour from 2026-10-01T08:00Z, serials PREFIX-0001...; seeded. From unit `drift_from` on, the
// sphere radius error grows by `drift_mm_per_unit` per unit.
inline std::vector<LineUnit> GenerateLine(const std::string& prefix, int n, unsigned seed, int drift_from = -1,
                                          double drift_mm_per_unit = 0, int first_hour = 0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> z(0.0, 1.0);
  std::vector<LineUnit> line;
  for (int i = 0; i < n; ++i) {
    LineUnit u;
    u.serial = fmt::format("{}-{:04d}", prefix, i + 1);
    const std::time_t t = 1790841600 + 3600 * static_cast<std::time_t>(first_hour + i);  // 2026-10-01T08:00:00Z
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    u.created_utc = buf;
    u.sigma_scale = 1 + kLineSigmaScatter * z(rng);
    u.radius_error_mm = 0.001 + kLineRadiusScatterMm * z(rng);
    if (drift_from >= 0 && i >= drift_from) u.radius_error_mm += drift_mm_per_unit * (i - drift_from + 1);
    u.rms_px = 0.03 + kLineRmsScatterPx * z(rng);
    u.kx_error = kLineConicScatter * z(rng);
    u.ky_error = kLineConicScatter * z(rng);
    line.push_back(u);
  }
  return line;
}

// Writes the record of `u` to `out` through report::UnitRecordWriter.
inline void WriteLineUnit(const std::string& out, const calib::CalibrationResult& base, const LineUnit& u) {
  calib::CalibrationResult r = base;
  r.camera.dist[0] *= u.sigma_scale;
  r.seidel->sigma_per_mm2 *= u.sigma_scale;
  for (auto& p : r.parameters) {
    if (p.name == "k1") p.value *= u.sigma_scale;
  }
  // The residuals scaled to the unit's RMS: a record's RMS is recomputed from its residuals.csv on ingestion.
  double sum2 = 0;
  int inliers = 0;
  for (const auto& c : r.residuals) {
    if (c.outlier) continue;
    sum2 += c.residual_px.squaredNorm();
    ++inliers;
  }
  const double scale = u.rms_px / std::sqrt(sum2 / inliers);
  for (auto& c : r.residuals) c.residual_px *= scale;
  r.rms_px = u.rms_px;
  r.per_view_rms_px.at(0) = u.rms_px;
  json body = RecordBody(r, u.serial, u.created_utc);
  auto& corrected = body["verification"]["corrected"];
  corrected = StageSphere(7.8, u.radius_error_mm, 0.0002);
  auto& paper = body["paper_cornea"]["corrected"];
  paper["kx"] = -0.43 + u.kx_error;
  paper["ky"] = -0.25 + u.ky_error;
  UnitRecordWriter writer(out);
  writer.WriteFile("calibration.yaml",
                   calib::CalibrationFileText(r, {"data/target-topographer.yaml", {"views/v1.png"}, u.created_utc}));
  writer.WriteFile("residuals.csv", ResidualsCsv(r));
  writer.Commit(body);
}

// A production line at scale: several stations over years, one station drifting, a few units failing. Unit i of
// `units` (serial SN-000001, ... in time order) is calibrated at start + i * span / units seconds (strictly
// increasing, so time order is serial order), on a station drawn at random; its numbers are GenerateLine's scatter.
struct FleetSpec {
  int units = 2000;
  int stations = 4;           // LINE-1 ... LINE-<stations>
  double years = 3;           // from 2024-01-01T00:00:00Z
  unsigned seed = 1;
  // A FAIL unit: its corrected sphere radius error is beyond the default limit (0.05 mm), a broken unit.
  double fail_fraction = 0.005;
  // The station whose sphere radius error drifts (0-based; -1 none), linearly from `drift_from` (a fraction of the
  // time span) to `drift_mm` at the end: 4 um = 2 sigma of the line's scatter.
  int drift_station = 2;
  double drift_from = 0.75, drift_mm = 0.004;
};

struct FleetLineUnit {
  LineUnit unit;
  int station = 0;
  bool fails = false;
};

inline constexpr std::time_t kFleetStartUtc = 1704067200;  // 2024-01-01T00:00:00Z
inline constexpr double kFleetFailRadiusErrorMm = 0.08;    // beyond the 0.05 mm limit

inline std::string FleetStationName(int station) { return fmt::format("LINE-{}", station + 1); }

inline std::vector<FleetLineUnit> GenerateFleet(const FleetSpec& spec) {
  std::mt19937 rng(spec.seed);
  std::normal_distribution<double> z(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::uniform_int_distribution<int> pick(0, spec.stations - 1);
  const double span_s = spec.years * 365.25 * 86400;
  std::vector<FleetLineUnit> fleet;
  fleet.reserve(static_cast<std::size_t>(spec.units));
  for (int i = 0; i < spec.units; ++i) {
    FleetLineUnit f;
    LineUnit& u = f.unit;
    u.serial = fmt::format("SN-{:06d}", i + 1);
    const double fraction = static_cast<double>(i) / spec.units;
    const std::time_t t = kFleetStartUtc + static_cast<std::time_t>(fraction * span_s);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    u.created_utc = buf;
    f.station = pick(rng);
    u.sigma_scale = 1 + kLineSigmaScatter * z(rng);
    u.radius_error_mm = 0.001 + kLineRadiusScatterMm * z(rng);
    if (f.station == spec.drift_station && fraction >= spec.drift_from) {
      u.radius_error_mm += spec.drift_mm * (fraction - spec.drift_from) / (1 - spec.drift_from);
    }
    u.rms_px = 0.03 + kLineRmsScatterPx * z(rng);
    u.kx_error = kLineConicScatter * z(rng);
    u.ky_error = kLineConicScatter * z(rng);
    f.fails = u01(rng) < spec.fail_fraction;
    if (f.fails) u.radius_error_mm = kFleetFailRadiusErrorMm;
    fleet.push_back(f);
  }
  return fleet;
}

// Where GenerateFleet's unit goes under `out`: <station>/<YYYY-MM>/<serial>, so that a station ingests a month at a
// time (`fleet ingest --station LINE-1 out/LINE-1/2024-01/*/`).
inline std::string FleetRecordDir(const std::string& out, const FleetLineUnit& f) {
  return fmt::format("{}/{}/{}/{}", out, FleetStationName(f.station), f.unit.created_utc.substr(0, 7), f.unit.serial);
}

}  // namespace topocal::report::testing

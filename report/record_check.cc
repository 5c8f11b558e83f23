#include "report/record_check.h"

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "calib/calibration_file.h"
#include "pipeline/unit_verification.h"
#include "report/unit_record_writer.h"
#include "util/io.h"
#include "util/json_section.h"
#include "util/sha256.h"

namespace topocal::report {
namespace {

using nlohmann::json;

// Recomputed and recorded numbers come from the same code on the same doubles, so they agree to the last bit on one
// machine; the bound only allows for another CPU's rounding of the same operations.
constexpr double kRelativeTolerance = 1e-9;
// residuals.csv keeps 6 decimals of each residual (px): its RMS can differ from the fit's by rounding alone.
constexpr double kResidualsRmsTolerancePx = 2e-6;

bool Agree(double recorded, double recomputed, double tolerance) {
  return std::abs(recorded - recomputed) <= tolerance * std::max(1.0, std::abs(recomputed));
}

std::string Shown(const json& v) {
  const std::string s = v.is_number() ? fmt::format("{:.12g}", v.get<double>()) : v.dump();
  return s.size() > 60 ? s.substr(0, 60) + "..." : s;
}

// Every leaf of `recomputed` must be in `recorded` with the same value (numbers within the tolerance).
void CompareBlocks(const UnitRecord& rec, const std::string& key, const json& recorded, const json& recomputed,
                   const std::string& sources) {
  const auto fail = [&](const std::string& what) {
    throw util::InputError(fmt::format("{}: {}: {} from {}: unit.json was changed after the record was written",
                                       rec.unit_json_path, key, what, sources));
  };
  if (recomputed.is_object()) {
    if (!recorded.is_object()) fail("must be an object");
    for (const auto& [name, value] : recomputed.items()) {
      if (!recorded.contains(name)) fail(fmt::format("{}: missing", name));
      CompareBlocks(rec, key + "." + name, recorded.at(name), value, sources);
    }
  } else if (recomputed.is_number() && !recomputed.is_boolean()) {
    if (!recorded.is_number() || !Agree(recorded.get<double>(), recomputed.get<double>(), kRelativeTolerance)) {
      fail(fmt::format("recorded {}, recomputed {}", Shown(recorded), Shown(recomputed)));
    }
  } else if (recorded != recomputed) {
    fail(fmt::format("recorded {}, recomputed {}", Shown(recorded), Shown(recomputed)));
  }
}

void CheckCalibrationRms(const UnitRecord& rec) {
  double sum2 = 0;
  int inliers = 0;
  for (const auto& r : rec.residuals) {
    if (r.outlier) continue;
    sum2 += r.dx_px * r.dx_px + r.dy_px * r.dy_px;
    ++inliers;
  }
  if (inliers == 0) {
    throw util::InputError(
        fmt::format("{}/residuals.csv: no inlier corner: the calibration RMS cannot be recomputed", rec.directory));
  }
  const double rms_px = std::sqrt(sum2 / inliers);
  if (std::abs(rms_px - rec.calibration_rms_px) > kResidualsRmsTolerancePx) {
    throw util::InputError(
        fmt::format("{}: calibration.rms_px: recorded {:.9g} px, recomputed {:.9g} px from "
                    "residuals.csv ({} inlier corners)",
                    rec.unit_json_path, rec.calibration_rms_px, rms_px, inliers));
  }
  if (rec.calibration.rms_px && !Agree(rec.calibration_rms_px, *rec.calibration.rms_px, kRelativeTolerance)) {
    throw util::InputError(fmt::format("{}: calibration.rms_px: recorded {:.9g} px, calibration.yaml says {:.9g} px",
                                       rec.unit_json_path, rec.calibration_rms_px, *rec.calibration.rms_px));
  }
}

void CheckAgainstCalibrationFile(const UnitRecord& rec, const std::string& key, double recorded, double in_file) {
  if (!Agree(recorded, in_file, kRelativeTolerance)) {
    throw util::InputError(fmt::format("{}: {}: recorded {:.12g}, calibration.yaml says {:.12g}", rec.unit_json_path,
                                       key, recorded, in_file));
  }
}

}  // namespace

void CheckRecordedCalibration(const UnitRecord& rec) {
  CheckCalibrationRms(rec);
  for (const CalibrationParameter& p : rec.parameters) {
    const auto it = rec.calibration.stddev.find(p.name);
    if (it == rec.calibration.stddev.end()) continue;  // not a lens parameter (the device's alignment)
    CheckAgainstCalibrationFile(rec, fmt::format("calibration.parameters[{}].stddev", p.name), p.stddev, it->second);
  }
  if (rec.seidel_sigma_per_mm2 && rec.calibration.sigma_per_mm2) {
    CheckAgainstCalibrationFile(rec, "calibration.seidel.sigma_per_mm2", *rec.seidel_sigma_per_mm2,
                                *rec.calibration.sigma_per_mm2);
  }
  if (rec.seidel_sigma_stddev_per_mm2 && rec.calibration.sigma_stddev_per_mm2) {
    CheckAgainstCalibrationFile(rec, "calibration.seidel.sigma_stddev_per_mm2", *rec.seidel_sigma_stddev_per_mm2,
                                *rec.calibration.sigma_stddev_per_mm2);
  }
}

void RecomputeRecordNumbers(const UnitRecord& rec, const RecordCheckOptions& options) {
  CheckRecordedCalibration(rec);
  if (!rec.config || !rec.topographer_camera) {
    throw util::InputError(
        fmt::format("{}: configuration: missing: the record's checks cannot be recomputed", rec.unit_json_path));
  }
  // unit.json as read by ReadUnitRecord (the same bytes: its digest is the record's id).
  const std::string text = util::ReadFile(rec.unit_json_path);
  if (util::Sha256Hex(text) != rec.unit_json_sha256) {
    throw util::InputError(fmt::format("{}: changed while it was being reported", rec.unit_json_path));
  }
  const json root = util::ParseJsonStrict(text, rec.unit_json_path);

  pipeline::UnitCalibration unit;
  unit.camera = rec.calibration.camera;
  unit.covariance = calib::ParameterCovarianceOf(rec.calibration);
  pipeline::CheckOptions check;
  check.uncertainty = rec.settings_uncertainty;
  check.seed = static_cast<std::uint32_t>(rec.settings_seed);
  check.jobs = options.jobs;

  // A check that ran when the record was written and fails now was not computed from these files.
  const auto rerun = [&](const char* key, const std::string& sources, const auto& compute) {
    try {
      return compute();
    } catch (const std::exception& e) {
      throw util::InputError(
          fmt::format("{}: {}: cannot be recomputed from {}: {}", rec.unit_json_path, key, sources, e.what()));
    }
  };
  if (rec.verification) {
    const std::string sources = "sphere_spots.csv, calibration.yaml and configuration";
    if (rec.verification->detected.empty()) {
      throw util::InputError(fmt::format("{}: files: no {}: the reference-sphere check cannot be recomputed",
                                         rec.unit_json_path, kSphereSpotsCsv));
    }
    const auto sphere = rerun("verification", sources, [&] {
      pipeline::SphereVerification v;
      v.detected = rec.verification->detected;
      v.spots_indexed = static_cast<int>(v.detected.size());
      v.spots_unassigned = rec.verification->spots_unassigned;
      v.spots_missing = rec.verification->spots_missing;
      return pipeline::VerifyOnReferenceSphere(std::move(v), rec.verification->radius_true_mm, unit,
                                               *rec.topographer_camera, *rec.config, check);
    });
    CompareBlocks(rec, "verification", root.at("verification"),
                  VerificationJson(sphere, rec.verification->image, check), sources);
  }
  const std::string sources = "calibration.yaml and configuration";
  const auto paper = rerun("paper_cornea", sources, [&] {
    return pipeline::SimulateThroughCalibratedCamera(unit, *rec.topographer_camera, *rec.config, check);
  });
  CompareBlocks(rec, "paper_cornea", root.at("paper_cornea"), PaperCorneaJson(paper, check), sources);
}

}  // namespace topocal::report

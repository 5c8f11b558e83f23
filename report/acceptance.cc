#include "report/acceptance.h"

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>
#include <tuple>

#include "util/io.h"
#include "util/json_section.h"

namespace topocal::report {
namespace {

using nlohmann::json;

constexpr const char* kSourcePower =
    "0.25 D: refraction and ophthalmic lens powers are prescribed in 0.25 D steps, the smallest power difference a "
    "clinician acts on. ISO 19980 (corneal topographers) verifies power on spherical test surfaces; its tolerance "
    "table was not available to us - compare with your copy.";
constexpr const char* kSourceRadius =
    "0.05 mm: the radius change that makes 0.25 D at R = 7.8 mm, dR = R^2 dP / (1000 (n_k - 1)) = 7.8^2 x 0.25 / "
    "337.5 = 0.045 mm, rounded up. ISO 19980 verifies radius on spherical test surfaces; compare with its table.";
constexpr const char* kSourceConic =
    "0.05: engineering limit between what correction achieves (k within 0.0004, docs/closed-loop.md) and what the "
    "uncorrected distortion of paper Table IV does (k_x moved by up to 0.86); set it from the harness's |dk| budget "
    "for the design.";
constexpr const char* kSourceChi2 =
    "4: the adequacy threshold of device calibrate: ball-image residuals twice the spot noise the fit assumed say "
    "the device model does not describe the unit (a ball moved between shots, a wrong certified radius, a changed "
    "lens).";
constexpr const char* kSourceRms =
    "0.5 px: sub-pixel corners of a sharp printed target reach 0.01-0.1 px RMS; above 0.5 px the corners are "
    "blurred or misdetected or the distortion model does not fit the lens.";

// One limit: {"max": > 0, "source": "where it comes from"}, nothing else.
Limit ReadLimit(util::JsonSection& limits, const char* name) {
  util::JsonSection one = limits.Child(name);
  const double max = one.Number("max");
  if (!(max > 0)) one.Fail(one.Key("max"), "must be a finite number > 0");
  const std::string source = one.String("source");
  if (source.empty()) one.Fail(one.Key("source"), "must be a non-empty string saying where the limit comes from");
  one.RejectUnknown();
  return {max, source};
}

// Guarded acceptance needs U; simple acceptance ignores it.
Check Judge(Check c, DecisionRule rule) {
  if (!c.error) {
    c.pass = false;
    return c;
  }
  if (rule == DecisionRule::kSimple) {
    c.pass = *c.error <= c.limit;
  } else if (!c.U) {
    c.pass = false;
    if (!c.note.empty()) c.note += "; ";
    c.note += "no U in the record: guarded acceptance cannot decide";
  } else {
    c.pass = *c.error + *c.U <= c.limit;
  }
  return c;
}

std::optional<double> QuantityU(const std::optional<UncertaintyBlock>& block, const char* key) {
  if (!block) return std::nullopt;
  const auto it = block->quantities.find(key);
  if (it == block->quantities.end()) return std::nullopt;
  return it->second.U;
}

// The simulated cornea's truth is exact and its images noise-free: the calibration is the only input of U.
Check PaperCheck(std::string id, std::string what, std::string unit, double error, std::optional<double> U,
                 double limit) {
  Check c{std::move(id), std::move(what), std::move(unit), error, U, {}, limit, false, ""};
  if (U) {
    c.budget = {{"calibration (its covariance)",
                 "unit.json: U (k = 2) halved; a simulation: truth exact, no image noise", 0.5 * *U}};
  }
  return c;
}

// The device fit's chi^2/dof from device.json (a fit statistic, compared with its limit directly); a device file
// without it cannot show the model describes the unit: not passed.
Check DeviceFitCheck(const DeviceStageRecord& device, const Limits& limits) {
  Check c{"device_chi2_per_dof", "device fit: \u03c7\u00b2/dof of the ball images", "", std::nullopt, std::nullopt,
          {}, limits.device_chi2_per_dof.max, false, "a fit statistic: compared with the limit directly"};
  const json& cal = device.file.calibration;
  const auto chi2 = cal.is_object() ? cal.find("chi2_per_dof") : cal.end();
  if (!cal.is_object() || chi2 == cal.end() || !chi2->is_number()) {
    c.note = "not judged: device.json has no fitted chi2/dof (a nominal device)";
    return c;
  }
  c.error = chi2->get<double>();
  c.pass = *c.error <= c.limit;
  return c;
}

}  // namespace

std::vector<NamedLimit> NamedLimits(const Limits& l) {
  return {{"calibration_rms_px", &l.calibration_rms_px, "px"},
          {"sphere_radius_error_mm", &l.sphere_radius_error_mm, "mm"},
          {"sphere_power_error_D", &l.sphere_power_error_D, "D"},
          {"paper_radius_error_mm", &l.paper_radius_error_mm, "mm"},
          {"paper_conic_error", &l.paper_conic_error, ""},
          {"device_chi2_per_dof", &l.device_chi2_per_dof, ""}};
}

Limits DefaultLimits() {
  Limits l;
  l.rule = DecisionRule::kGuarded;
  l.calibration_rms_px = {kDefaultCalibrationRmsPx, kSourceRms};
  l.sphere_radius_error_mm = {kDefaultSphereRadiusErrorMm, kSourceRadius};
  l.sphere_power_error_D = {kDefaultSpherePowerErrorD, kSourcePower};
  l.paper_radius_error_mm = {kDefaultPaperRadiusErrorMm, kSourceRadius};
  l.paper_conic_error = {kDefaultPaperConicError, kSourceConic};
  l.device_chi2_per_dof = {kDefaultDeviceChi2PerDof, kSourceChi2};
  l.origin = "built-in defaults (data/limits.json)";
  return l;
}

Limits LoadLimits(const std::string& path) {
  const json root = util::ParseJsonStrict(util::ReadFile(path), path);
  util::JsonSection r(root, path, "");
  Limits l;
  const json& rule = r.Get("decision_rule");
  if (rule == "guarded") {
    l.rule = DecisionRule::kGuarded;
  } else if (rule == "simple") {
    l.rule = DecisionRule::kSimple;
  } else {
    r.Fail("decision_rule", "must be \"guarded\" or \"simple\"");
  }
  const json& format = r.Get("format");
  if (!format.is_string() || format.get<std::string>() != kLimitsFormat) {
    r.Fail("format", fmt::format("must be \"{}\"", kLimitsFormat));
  }
  if (!util::JsonIntegerWithin(r.Get("format_version"), kLimitsFormatVersion, kLimitsFormatVersion)) {
    r.Fail("format_version", fmt::format("must be {}", kLimitsFormatVersion));
  }
  util::JsonSection limits = r.Child("limits");
  l.calibration_rms_px = ReadLimit(limits, "calibration_rms_px");
  l.sphere_radius_error_mm = ReadLimit(limits, "sphere_radius_error_mm");
  l.sphere_power_error_D = ReadLimit(limits, "sphere_power_error_D");
  l.paper_radius_error_mm = ReadLimit(limits, "paper_radius_error_mm");
  l.paper_conic_error = ReadLimit(limits, "paper_conic_error");
  l.device_chi2_per_dof = limits.Has("device_chi2_per_dof") ? ReadLimit(limits, "device_chi2_per_dof")
                                                            : Limit{kDefaultDeviceChi2PerDof, kSourceChi2};
  limits.RejectUnknown();
  r.RejectUnknown();
  l.origin = path;
  return l;
}

std::string ToString(DecisionRule rule) { return rule == DecisionRule::kGuarded ? "guarded" : "simple"; }

std::string DecisionRuleText(DecisionRule rule) {
  if (rule == DecisionRule::kGuarded) {
    return "Guarded acceptance (ILAC-G8:09/2019, guard band w = U; ISO 14253-1:2017 conformance zone): a check "
           "passes when |error| + U \u2264 limit, U the expanded uncertainty (k = 2) of the uncertainty budget: the "
           "calibration's covariance carried to the number, the repeatability and the reference ball's "
           "certificate. A check without the calibration's U in the record fails. The calibration RMS is compared "
           "with its limit directly.";
  }
  return "Simple acceptance (ILAC-G8:09/2019, shared risk): a check passes when |error| \u2264 limit; U (k = 2) "
         "is shown but not used.";
}

bool BudgetOptions::IsValid(std::string* why) const {
  if (ball_radius_U_mm && !(std::isfinite(*ball_radius_U_mm) && *ball_radius_U_mm >= 0 && *ball_radius_U_mm < 1.0)) {
    if (why) *why = "the ball's certificate U must be a finite number in [0, 1) mm";
    return false;
  }
  return true;
}

double CombinedStandardUncertainty(const std::vector<BudgetTerm>& terms) {
  double sum = 0;
  for (const BudgetTerm& t : terms) sum += t.u * t.u;
  return std::sqrt(sum);
}

std::string CanonicalLimits(const Limits& l) {
  return fmt::format("decision_rule={};calibration_rms_px={};sphere_radius_error_mm={};sphere_power_error_D={};"
                     "paper_radius_error_mm={};paper_conic_error={};device_chi2_per_dof={}",
                     ToString(l.rule), l.calibration_rms_px.max, l.sphere_radius_error_mm.max,
                     l.sphere_power_error_D.max, l.paper_radius_error_mm.max, l.paper_conic_error.max,
                     l.device_chi2_per_dof.max);
}

std::vector<Check> PaperCorneaRows(const UnitRecord& rec, const Limits& limits) {
  std::vector<Check> rows;
  const PaperCornea& p = rec.paper;
  for (const char* key : {"rx_mm", "ry_mm"}) {
    const std::string name = key[1] == 'x' ? "r_x" : "r_y";
    // One id per row (the JSON's key for it); the threshold they share is paper_radius_error_mm.
    const std::string id = fmt::format("paper_{}_error_mm", key[1] == 'x' ? "rx" : "ry");
    rows.push_back(Judge(PaperCheck(id, fmt::format("paper cornea: {} error, corrected", name), "mm",
                                         std::abs(p.corrected.at(key) - p.truth.at(key)),
                                         QuantityU(p.uncertainty, key), limits.paper_radius_error_mm.max),
                              limits.rule));
  }
  for (const char* key : {"kx", "ky"}) {
    const std::string name = key[1] == 'x' ? "k_x" : "k_y";
    rows.push_back(Judge(PaperCheck(fmt::format("paper_{}_error", key),
                                         fmt::format("paper cornea: {} error, corrected", name), "",
                                         std::abs(p.corrected.at(key) - p.truth.at(key)),
                                         QuantityU(p.uncertainty, key), limits.paper_conic_error.max),
                              limits.rule));
  }
  return rows;
}

namespace {

// The reference sphere's radius and power errors with their budgets (calibration U from the record, repeatability
// measured or defaulted, the ball's certificate), or "not verified" without a verification.
std::vector<Check> SphereChecks(const UnitRecord& rec, const Limits& limits, const BudgetOptions& budget) {
  std::vector<Check> out;
  if (rec.verification) {
    const SphereVerification& s = *rec.verification;
    // Calibration: the record's own U of the radius when it has one; else radius = (r_x + r_y) / 2 and the U of a
    // mean is at most the mean of the U's (equality for full correlation).
    std::optional<double> u_radius = QuantityU(s.uncertainty, "radius_mm");
    std::string radius_note = u_radius ? "U(calibration) of (r_x + r_y) / 2 from its covariance" : "";
    if (auto ux = QuantityU(s.uncertainty, "rx_mm"), uy = QuantityU(s.uncertainty, "ry_mm"); !u_radius && ux && uy) {
      u_radius = 0.5 * (*ux + *uy);
      radius_note = "U(calibration) = (U(r_x) + U(r_y)) / 2, the bound for fully correlated r_x, r_y";
    }
    std::optional<double> u_power = QuantityU(s.uncertainty, "central_axial_power_D");
    std::string power_note = u_power ? "U(calibration) of the central power from its covariance" : "";
    const double radius_mm = s.corrected.at("radius_mm");
    // dP/dR at the ball's true radius: P = 1000 (n_k - 1) / R.
    const double dP_dR = 1000.0 * (s.keratometric_index - 1.0) / (s.radius_true_mm * s.radius_true_mm);
    if (!u_power && u_radius && radius_mm > 0) {
      u_power = 1000.0 * (s.keratometric_index - 1.0) * *u_radius / (radius_mm * radius_mm);
      power_note = "U(calibration) = 1000 (n_k - 1) U(R) / R^2, first order";
    }
    // The other two inputs, in mm of radius.
    const bool cert_given = budget.ball_radius_U_mm.has_value();
    const double u_cert_mm = 0.5 * budget.ball_radius_U_mm.value_or(kDefaultBallRadiusUMm);
    const std::string cert_source =
        cert_given ? fmt::format("certificate: U = {} mm (k = 2), halved", budget.ball_radius_U_mm.value())
                   : fmt::format("default U = {} mm (k = 2), halved: no certificate value given (ISO 10343 test-sphere "
                                 "requirement)",
                                 kDefaultBallRadiusUMm);
    BudgetTerm rep_radius{"repeatability", "", kDefaultRepeatabilityRadiusMm};
    BudgetTerm rep_power{"repeatability", "", dP_dR * kDefaultRepeatabilityRadiusMm};
    if (s.repeatability) {
      rep_radius.u = s.repeatability->radius_stddev_mm;
      rep_power.u = s.repeatability->power_stddev_D;
      rep_radius.source = rep_power.source =
          fmt::format("sample standard deviation of {} repeated images of the sphere (unit.json)",
                      s.repeatability->images);
    } else {
      rep_radius.source = fmt::format("default {} mm (k = 1): no repeated images in the record", kDefaultRepeatabilityRadiusMm);
      rep_power.source = fmt::format("default {} mm (k = 1) x dP/dR = {} D/mm: no repeated images in the record",
                                     kDefaultRepeatabilityRadiusMm, fmt::format("{:.4g}", dP_dR));
    }
    Check radius{"sphere_radius_error_mm", "reference sphere: radius error, corrected", "mm",
                 std::abs(s.corrected.at("radius_error_mm")), std::nullopt, {}, limits.sphere_radius_error_mm.max,
                 false, radius_note};
    Check power{"sphere_power_error_D", "reference sphere: power error, corrected", "D",
                std::abs(s.corrected.at("power_error_D")), std::nullopt, {}, limits.sphere_power_error_D.max, false,
                power_note};
    if (u_radius) {
      radius.budget = {{"calibration (its covariance)", "unit.json: U (k = 2) halved", 0.5 * *u_radius},
                       rep_radius,
                       {"reference ball certificate", cert_source, u_cert_mm}};
      radius.U = 2.0 * CombinedStandardUncertainty(radius.budget);
      radius.note += "; U = 2 \u221a(\u03a3 u\u00b2) over the budget";
    }
    if (u_power) {
      power.budget = {{"calibration (its covariance)", "unit.json: U (k = 2) halved", 0.5 * *u_power},
                      rep_power,
                      {"reference ball certificate",
                       cert_source + fmt::format(", x dP/dR = {:.4g} D/mm (true power from the certified radius)", dP_dR),
                       dP_dR * u_cert_mm}};
      power.U = 2.0 * CombinedStandardUncertainty(power.budget);
      power.note += "; U = 2 \u221a(\u03a3 u\u00b2) over the budget";
    }
    out.push_back(Judge(radius, limits.rule));
    out.push_back(Judge(power, limits.rule));
  } else {
    for (const auto& [id, what, unit, limit] :
         {std::tuple{"sphere_radius_error_mm", "reference sphere: radius error, corrected", "mm",
                     limits.sphere_radius_error_mm.max},
          std::tuple{"sphere_power_error_D", "reference sphere: power error, corrected", "D",
                     limits.sphere_power_error_D.max}}) {
      out.push_back({id, what, unit, std::nullopt, std::nullopt, {}, limit, false,
                          "not verified: the record has no reference-sphere verification"});
    }
  }
  return out;
}

}  // namespace

Verdict Evaluate(const UnitRecord& rec, const Limits& limits, const BudgetOptions& budget) {
  std::string why;
  if (!budget.IsValid(&why)) throw util::InputError("BudgetOptions: " + why);
  Verdict v;
  {
    Check c{"calibration_rms_px", "calibration: reprojection RMS", "px", rec.calibration_rms_px, std::nullopt,
            {}, limits.calibration_rms_px.max, false, "a fit statistic: compared with the limit directly"};
    c.pass = rec.calibration_rms_px <= c.limit;
    v.checks.push_back(c);
  }
  for (Check& c : SphereChecks(rec, limits, budget)) v.checks.push_back(std::move(c));
  if (rec.device) v.checks.push_back(DeviceFitCheck(*rec.device, limits));
  v.pass = true;
  for (const Check& c : v.checks) v.pass = v.pass && c.pass;
  return v;
}

std::vector<std::string> FailedChecks(const Verdict& verdict) {
  std::vector<std::string> out;
  for (const Check& c : verdict.checks) {
    if (c.pass) continue;
    const std::string unit = c.unit.empty() ? "" : " " + c.unit;
    // Why: the error beyond the limit, or (guarded acceptance) the error with its U beyond it, or no U to decide.
    if (!c.error) {
      out.push_back(fmt::format("{} ({})", c.what, c.note));
    } else if (*c.error > c.limit) {
      out.push_back(fmt::format("{} |error| {:.3g}{} > limit {:.3g}{}", c.what, *c.error, unit, c.limit, unit));
    } else if (c.U) {
      out.push_back(fmt::format("{} |error| {:.3g}{} + U {:.2g}{} > limit {:.3g}{} (guarded acceptance)", c.what,
                                *c.error, unit, *c.U, unit, c.limit, unit));
    } else {
      out.push_back(fmt::format("{} |error| {:.3g}{} ({})", c.what, *c.error, unit, c.note));
    }
  }
  return out;
}

}  // namespace topocal::report

#pragma once
// Pass/fail of one unit against configurable limits, with the decision rule stated.
//
// Limits file (JSON, strict: every key required, no unknown key, each max finite and > 0):
//   {"format": "topocal-limits", "format_version": 1,
//    "decision_rule": "guarded" | "simple",
//    "limits": {"calibration_rms_px":     {"max": 0.5,  "source": "..."},
//               "sphere_radius_error_mm": {"max": 0.05, "source": "..."},
//               "sphere_power_error_D":   {"max": 0.25, "source": "..."},
//               "paper_radius_error_mm":  {"max": 0.05, "source": "..."},
//               "paper_conic_error":      {"max": 0.05, "source": "..."}}}
// data/limits.json holds the defaults below (a test keeps the two equal).
//
// Decision rules (ILAC-G8:09/2019, ISO 14253-1:2017):
//   guarded: PASS when |error| + U <= limit (guard band w = U, k = 2): a PASS holds with about 97.7 % confidence
//            for a normal error (one-sided, k = 2). A check whose U is not in the record cannot be decided and FAILs.
//   simple:  PASS when |error| <= limit (shared risk; U is shown, not used).
// The calibration RMS is a statistic of the fit, not a measured error: both rules compare it with its limit alone.
// A record without a reference-sphere verification FAILs the sphere checks (the unit was not verified).
#include <optional>
#include <string>
#include <vector>

#include "report/unit_record_reader.h"

namespace topocal::report {

inline constexpr const char* kLimitsFormat = "topocal-limits";
inline constexpr int kLimitsFormatVersion = 1;

enum class DecisionRule { kGuarded, kSimple };

struct Limit {
  double max = 0;
  std::string source;  // where the number comes from, printed on the report
};

struct Limits {
  DecisionRule rule = DecisionRule::kGuarded;
  Limit calibration_rms_px, sphere_radius_error_mm, sphere_power_error_D, paper_radius_error_mm, paper_conic_error;
  // Judges records with a device stage only; optional in a limits file (the default when absent).
  Limit device_chi2_per_dof;
  std::string origin;  // the limits file, or "built-in defaults"
};

// Default limits and their sources (mirrored in data/limits.json).
//  0.25 D: refraction and ophthalmic lens powers are prescribed in 0.25 D steps, the smallest power difference a
//  clinician acts on. 0.05 mm: the radius change that makes 0.25 D at the reference radius 7.8 mm,
//  dR = R^2 dP / (1000 (n_k - 1)) = 7.8^2 x 0.25 / 337.5 = 0.045 mm, rounded up to 0.05 mm.
inline constexpr double kDefaultSpherePowerErrorD = 0.25;
inline constexpr double kDefaultSphereRadiusErrorMm = 0.05;
inline constexpr double kDefaultPaperRadiusErrorMm = 0.05;
//  Conic constant: correction recovers k within 0.0004 (docs/closed-loop.md), the uncorrected distortion of paper
//  Table IV moves k_x by up to 0.86; 0.05 sits between the two. An engineering limit: set it from the harness's
//  |dk| budget for the design.
inline constexpr double kDefaultPaperConicError = 0.05;
//  Calibration RMS: sub-pixel corners of a sharp printed target reach 0.01-0.1 px (docs/unit-record.md example:
//  0.0125 px); above 0.5 px the corners are blurred or misdetected or the model does not fit.
inline constexpr double kDefaultCalibrationRmsPx = 0.5;
//  Device fit chi^2/dof (the ball images' residuals over the spot noise the fit assumed): 4, the adequacy threshold
//  of `device calibrate` (calib::DeviceFitOptions::max_chi2_per_dof) - residuals twice the noise say the device model
//  does not describe the unit (a ball moved between shots, a wrong certified radius, a lens changed).
inline constexpr double kDefaultDeviceChi2PerDof = 4.0;

// Every limit with its key and unit, in the order reports list them (one list for the HTML, the JSON and the tests).
struct NamedLimit {
  const char* name;
  const Limit* limit;
  const char* unit;  // "px", "mm", "D" or ""
};
std::vector<NamedLimit> NamedLimits(const Limits& limits);

Limits DefaultLimits();
// Reads a limits file. Throws util::InputError "PATH: KEY: problem".
Limits LoadLimits(const std::string& path);
std::string ToString(DecisionRule rule);
// One sentence stating the rule, printed on the report.
std::string DecisionRuleText(DecisionRule rule);

// The measurement uncertainty of the reference-sphere checks beyond the calibration. The error judged is
// measured - true, so u(error)^2 = u(calibration)^2 + u(repeatability)^2 + u(certificate)^2 (GUM, Eq. 10, the
// three inputs independent, sensitivity 1 once converted to the quantity's unit).
//
// Reference ball certificate: the expanded uncertainty (k = 2) of the ball's certified radius, from the user
// (`topocal report --ball-radius-U-mm`). Without it the default below is used and the report says so.
//  1 um: ISO 10343 (ophthalmometers) requires its test spheres' radius to be known to <= 1 um; a ball that does not
//  meet it must be given with its own certificate's number.
inline constexpr double kDefaultBallRadiusUMm = 0.001;
// Repeatability (k = 1) of one measurement of the sphere's radius when the record holds no repeated images of it.
//  5 um: half of the 0.01 mm radius accuracy topographer makers commonly state on calibration spheres; a
//  conservative engineering default, to be replaced by the sample standard deviation of repeated images
//  (unit.json verification.repeatability, docs/unit-record.md). Its power equivalent goes through
//  dP/dR = -1000 (n_k - 1) / R^2 (0.028 D at 7.8 mm).
inline constexpr double kDefaultRepeatabilityRadiusMm = 0.005;

struct BudgetOptions {
  std::optional<double> ball_radius_U_mm;  // the certificate's U (k = 2); default kDefaultBallRadiusUMm
  bool IsValid(std::string* why) const;
};

// One input of a combined standard uncertainty, already in the quantity's unit.
struct BudgetTerm {
  std::string name;    // "calibration (Monte Carlo)", "reference ball certificate", "repeatability"
  std::string source;  // where the number comes from
  double u = 0;        // standard uncertainty, k = 1
};

// u_c = sqrt(sum u_i^2), U = 2 u_c.
double CombinedStandardUncertainty(const std::vector<BudgetTerm>& terms);

struct Check {
  std::string id;           // the limit's key
  std::string what;         // e.g. "reference sphere: radius error, corrected"
  std::string unit;         // "mm", "D", "px", ""
  std::optional<double> error;  // |error| (or the RMS); absent when the record has nothing to judge
  std::optional<double> U;      // expanded uncertainty, k = 2: 2 x CombinedStandardUncertainty(budget)
  std::vector<BudgetTerm> budget;  // the contributions to U (empty when U is absent or not used)
  double limit = 0;
  bool pass = false;
  std::string note;         // how U was obtained, or why the check failed without a number
};

struct Verdict {
  std::vector<Check> checks;
  bool pass = false;  // every check passes
};

// The verdict rests on evidence the fit did not use: the calibration's RMS and the reference sphere measured
// through the unit against its certificate. The simulated paper cornea is not among the checks: simulated through
// the unit's own fitted calibration and corrected by the same calibration, its error is the same rounding noise
// for a good unit and a broken one (docs/report.md).
Verdict Evaluate(const UnitRecord& record, const Limits& limits, const BudgetOptions& budget = {});

// The simulated paper cornea's corrected errors, an informative row each ("what this unit's calibration does to a
// typical eye"): compared with the informative thresholds paper_radius_error_mm and paper_conic_error, never part
// of the verdict.
std::vector<Check> PaperCorneaRows(const UnitRecord& record, const Limits& limits);

// The failed checks in words, one each, for the report's first page and the CLI's last line, with the reason:
// "reference sphere: radius error, corrected |error| 0.062 mm > limit 0.05 mm", "... |error| 0.041 mm + U 0.012 mm
// > limit 0.05 mm (guarded acceptance)", or the check's note when it could not be decided. Empty on PASS.
std::vector<std::string> FailedChecks(const Verdict& verdict);

// The limits as canonical text (rule and every max, shortest round-trip form; the sources are prose and left out):
// hashed into the report id, so that the same record judged against other limits gets another id.
std::string CanonicalLimits(const Limits& limits);

}  // namespace topocal::report

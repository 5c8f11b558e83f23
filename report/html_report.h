#pragma once
// The QA report of one unit: a single self-contained HTML page (no external resource of any kind: plots are inline
// SVG, the record's maps are PNG data: URIs, the CSS is inline) that prints to A4, and the same verdict as JSON.
//
// Sections: verdict banner; device identity; sign-off block (operator, station, reference certificates, blank
// signature and date lines); method and decision rule; calibration parameters +- U (k = 2) and the Seidel sigma;
// residual plots (per-view RMS, residual vectors over the image, the calibrated model's distortion field); reference
// sphere and paper cornea before/after correction (tables and maps); comparison with the unit's previous calibration
// when one is given; the acceptance checks against the limits with their sources and the uncertainty budgets;
// appendix: inputs and record files with their SHA-256.
//
// Deterministic: the page depends only on its inputs (no clock, no locale), so the same inputs give the same bytes.
// The report id, `<serial>-<first 12 hex digits of SHA-256(ReportIdText)>`, is in the title, at the top of the
// page and in the header and footer repeated on every printed page, with "Page n of N".
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "report/acceptance.h"
#include "report/unit_record_reader.h"

namespace topocal::report {

inline constexpr int kReportIdHexDigits = 12;
inline constexpr const char* kReportJsonFormat = "topocal-report";
inline constexpr int kReportJsonFormatVersion = 1;

// Who signs, where, against which artefacts: from the user (`topocal report --operator ...`); empty = not given,
// printed as such.
struct SignOff {
  std::string operator_name, station, ball_certificate_id, target_certificate_id;
};

struct ReportInputs {
  Limits limits = DefaultLimits();
  BudgetOptions budget;
  SignOff sign_off;
  const UnitRecord* previous = nullptr;  // the unit's previous calibration (same serial), compared when given
  // Throws util::InputError when `previous` is another unit's record or the budget options are invalid.
  void Validate(const UnitRecord& record) const;
};

// What the report id hashes, one "key=value" per line: the record (SHA-256 of unit.json), the limits and decision
// rule (CanonicalLimits), the budget's inputs, the sign-off and the previous record. A change to any of them -
// a limit, the rule, the certificate's U, the operator - gives another id.
std::string ReportIdText(const UnitRecord& record, const ReportInputs& inputs);
std::string ReportId(const UnitRecord& record, const ReportInputs& inputs);

// Standard base64 (RFC 4648) with padding.
std::string Base64(std::string_view bytes);

// The HTML text. Throws std::runtime_error if the distortion field of the calibration cannot be evaluated.
std::string RenderHtmlReport(const UnitRecord& record, const ReportInputs& inputs);

// The verdict as JSON (docs/report.md, "JSON"): format, report id, every check with its value, U, budget, limit and
// result, the decision rule, the limits, the sign-off and the overall verdict - the same Evaluate() as the page.
nlohmann::json ReportJson(const UnitRecord& record, const ReportInputs& inputs);

}  // namespace topocal::report

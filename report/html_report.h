#pragma once
// The QA report of one unit: a single self-contained HTML page (no external resource of any kind: plots are inline
// SVG, the record's maps are PNG data: URIs, the CSS is inline) that prints to A4.
//
// Sections: verdict banner; device identity; method and decision rule; inputs and record files with SHA-256;
// calibration parameters +- U (k = 2) and the Seidel sigma; residual plots (per-view RMS, residual vectors over the
// image, the calibrated model's distortion field); reference sphere and paper cornea before/after correction
// (tables and maps); the acceptance checks against the limits with their sources.
//
// Deterministic: the page depends only on the record and the limits (no clock, no locale), so the same record gives
// the same bytes. The report id, `<serial>-<first 12 hex digits of SHA-256(unit.json)>`, is in the title, at the top
// of the page and in the header and footer repeated on every printed page.
#include <string>

#include "report/acceptance.h"
#include "report/unit_record_reader.h"

namespace topocal::report {

inline constexpr int kReportIdHexDigits = 12;

std::string ReportId(const UnitRecord& record);

// Standard base64 (RFC 4648) with padding.
std::string Base64(std::string_view bytes);

// The HTML text. Throws std::runtime_error if the distortion field of the calibration cannot be evaluated.
std::string RenderHtmlReport(const UnitRecord& record, const Limits& limits);

}  // namespace topocal::report

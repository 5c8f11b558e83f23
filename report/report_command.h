#pragma once
// `topocal report`: the QA report of one unit record (report/html_report.h), one self-contained HTML file, and the
// same verdict as JSON.
#include <optional>
#include <ostream>
#include <string>

#include "report/html_report.h"

namespace topocal::report {

struct ReportRequest {
  std::string unit_dir;      // the unit record (units/SN/)
  std::string out_path;      // the HTML report
  std::string json_path;     // the checks and verdict as JSON; empty: none
  std::string limits_path;   // acceptance limits (JSON); empty: the built-in ones
  std::string previous_dir;  // the unit's previous record, compared on the report; empty: none
  SignOff sign_off;
  std::optional<double> ball_radius_U_mm;  // the reference ball's certificate U (k = 2); empty: the default
};

// Everything is read and checked before the output is touched; then the report (and JSON) are written together and
// the verdict printed to `out`. util::InputError for a bad record, limits file or option; util::VerdictFailed,
// after the report is written, when the unit fails.
void RunReport(const ReportRequest& request, std::ostream& out);

}  // namespace topocal::report

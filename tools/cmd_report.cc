// topocal report: the QA report of one unit record (report/html_report.h), one self-contained HTML file, and the
// same verdict as JSON.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <memory>
#include <optional>

#include "report/acceptance.h"
#include "report/html_report.h"
#include "report/record_check.h"
#include "report/unit_record_reader.h"
#include "tools/commands.h"
#include "util/io.h"
#include "util/json_section.h"

namespace topocal::tools {
namespace {

struct ReportArgs {
  std::string unit, out, limits, json, previous;
  report::SignOff sign_off;
  std::optional<double> ball_radius_U_mm;
};

void Run(const ReportArgs& a) {
  // Everything is read and checked before the output is touched: a bad record or limits file leaves no report.
  report::ReportInputs in;
  in.limits = a.limits.empty() ? report::DefaultLimits() : report::LoadLimits(a.limits);
  in.budget.ball_radius_U_mm = a.ball_radius_U_mm;
  in.sign_off = a.sign_off;
  const report::UnitRecord record = report::ReadUnitRecord(a.unit);
  report::RecomputeRecordNumbers(record);  // the verdict's numbers, recomputed from the record's own files
  std::optional<report::UnitRecord> previous;
  if (!a.previous.empty()) {
    previous = report::ReadUnitRecord(a.previous);
    // Its numbers go on the signed comparison: recomputed from its own files like the record's (an edited previous
    // unit.json was shown as it stood).
    report::RecomputeRecordNumbers(*previous);
    in.previous = &*previous;
  }
  in.Validate(record);
  const std::string html = report::RenderHtmlReport(record, in);
  const nlohmann::json verdict_json = report::ReportJson(record, in);
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out, html);
  if (!a.json.empty()) outputs.AddFile(a.json, util::JsonFileText(verdict_json));
  outputs.Commit();
  const report::Verdict verdict = report::Evaluate(record, in.limits, in.budget);
  fmt::print("{}: report {} for unit {}: {}\n", a.out, report::ReportId(record, in), record.serial,
             verdict.pass ? "PASS" : "FAIL");
  if (!verdict.pass) {
    throw VerdictFailed(fmt::format("unit {}: FAIL: {}", record.serial, fmt::join(report::FailedChecks(verdict), "; ")));
  }
}

}  // namespace

void AddReportCommand(CLI::App& app) {
  auto a = std::make_shared<ReportArgs>();
  auto* cmd = app.add_subcommand("report", "QA report of a unit record: one self-contained HTML file (printable)");
  cmd->add_option("--unit", a->unit, "Unit record directory written by `topocal unit calibrate` (units/SN/)")
      ->required();
  cmd->add_option("--out", a->out, "Output HTML file")->required();
  cmd->add_option("--json", a->json, "Also write the checks and verdict as JSON (docs/report.md)");
  cmd->add_option("--limits", a->limits, "Acceptance limits (JSON, see data/limits.json); default: built in");
  cmd->add_option("--previous", a->previous, "The unit's previous record (same serial), compared on the report");
  cmd->add_option("--operator", a->sign_off.operator_name, "Sign-off: who calibrated the unit");
  cmd->add_option("--station", a->sign_off.station, "Sign-off: calibration station");
  cmd->add_option("--ball-certificate", a->sign_off.ball_certificate_id, "Sign-off: reference ball certificate id");
  cmd->add_option("--target-certificate", a->sign_off.target_certificate_id,
                  "Sign-off: calibration target certificate id");
  cmd->add_option("--ball-radius-U-mm", a->ball_radius_U_mm,
                  "Expanded uncertainty (k = 2) of the reference ball's radius from its certificate, mm (default "
                  "0.001, reported as a default)");
  cmd->callback([a] { Run(*a); });
}

}  // namespace topocal::tools

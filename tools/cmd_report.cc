// topocal report: the QA report of one unit record (report/html_report.h), one self-contained HTML file.
#include <memory>

#include <fmt/format.h>

#include "model/io.h"
#include "report/acceptance.h"
#include "report/html_report.h"
#include "report/unit_record_reader.h"
#include "tools/commands.h"

namespace topocal::tools {
namespace {

struct ReportArgs {
  std::string unit, out, limits;
};

void Run(const ReportArgs& a) {
  // Everything is read and checked before the output is touched: a bad record or limits file leaves no report.
  const report::Limits limits = a.limits.empty() ? report::DefaultLimits() : report::LoadLimits(a.limits);
  const report::UnitRecord record = report::ReadUnitRecord(a.unit);
  const std::string html = report::RenderHtmlReport(record, limits);
  model::WriteFileAtomic(a.out, html);
  const report::Verdict verdict = report::Evaluate(record, limits);
  fmt::print("{}: report {} for unit {}: {}\n", a.out, report::ReportId(record), record.serial,
             verdict.pass ? "PASS" : "FAIL");
  if (!verdict.pass) {
    int failed = 0;
    for (const auto& c : verdict.checks) failed += c.pass ? 0 : 1;
    throw VerdictFailed(fmt::format("unit {}: FAIL ({} check(s) outside the limits; the report says which)",
                                    record.serial, failed));
  }
}

}  // namespace

void AddReportCommand(CLI::App& app) {
  auto a = std::make_shared<ReportArgs>();
  auto* cmd = app.add_subcommand("report", "QA report of a unit record: one self-contained HTML file (printable)");
  cmd->add_option("--unit", a->unit, "Unit record directory written by `topocal unit calibrate` (units/SN/)")
      ->required();
  cmd->add_option("--out", a->out, "Output HTML file")->required();
  cmd->add_option("--limits", a->limits, "Acceptance limits (JSON, see data/limits.json); default: built in");
  cmd->callback([a] { Run(*a); });
}

}  // namespace topocal::tools

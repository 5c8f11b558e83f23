#include "report/report_command.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "report/acceptance.h"
#include "report/record_check.h"
#include "report/unit_record_reader.h"
#include "util/io.h"
#include "util/json_section.h"
#include "util/verdict.h"

namespace topocal::report {

void RunReport(const ReportRequest& a, std::ostream& out) {
  ReportInputs in;
  in.limits = a.limits_path.empty() ? DefaultLimits() : LoadLimits(a.limits_path);
  in.budget.ball_radius_U_mm = a.ball_radius_U_mm;
  in.sign_off = a.sign_off;
  const UnitRecord record = ReadUnitRecord(a.unit_dir);
  RecomputeRecordNumbers(record);  // the verdict's numbers, recomputed from the record's own files
  std::optional<UnitRecord> previous;
  if (!a.previous_dir.empty()) {
    previous = ReadUnitRecord(a.previous_dir);
    // Its numbers go on the signed comparison: recomputed from its own files like the record's (an edited previous
    // unit.json would otherwise be shown as it stood).
    RecomputeRecordNumbers(*previous);
    in.previous = &*previous;
  }
  in.Validate(record);
  const std::string html = RenderHtmlReport(record, in);
  const nlohmann::json verdict_json = ReportJson(record, in);
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out_path, html);
  if (!a.json_path.empty()) outputs.AddFile(a.json_path, util::JsonFileText(verdict_json));
  outputs.Commit();
  const Verdict verdict = Evaluate(record, in.limits, in.budget);
  out << fmt::format("{}: report {} for unit {}: {}\n", a.out_path, ReportId(record, in), record.serial,
                     verdict.pass ? "PASS" : "FAIL");
  if (!verdict.pass) {
    throw util::VerdictFailed(fmt::format("unit {}: FAIL: {}", record.serial, fmt::join(FailedChecks(verdict), "; ")));
  }
}

}  // namespace topocal::report

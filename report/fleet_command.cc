#include "report/fleet_command.h"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <cstdint>
#include <utility>

#include "report/acceptance.h"
#include "report/fleet_db.h"
#include "report/fleet_report.h"
#include "report/record_check.h"
#include "report/unit_record_reader.h"
#include "report/unit_record_writer.h"
#include "util/io.h"
#include "util/json_section.h"

namespace topocal::report {

void RunFleetIngest(const FleetIngestRequest& a, std::ostream& out) {
  if (a.station.empty()) throw util::InputError("--station: must not be empty");
  std::vector<UnitRecord> records;
  for (const std::string& dir : a.records) {
    if (IsRecordLeftover(dir)) {
      util::Log(a.log, fmt::format("{}: skipped: a staging folder a killed run left (the next run for that unit "
                                   "removes it)",
                                   dir));
      continue;
    }
    records.push_back(ReadUnitRecord(dir));
    if (a.recompute) RecomputeRecordNumbers(records.back());
  }
  if (records.empty()) throw util::InputError("no unit record to ingest (every directory given was a leftover)");
  FleetDb db(a.db, /*create=*/true);
  const IngestResult r = db.Ingest(records, a.station);
  fmt::print(out, "{}: {} record(s) added, {} already present; {} record(s) in the database\n", a.db, r.added,
             r.present, db.Totals().records);
}

// The histograms and the count of serials come from SQLite; the CSV, when asked, from a second pass.
void RunFleetReport(const FleetReportRequest& a, std::ostream& out) {
  const Limits limits = a.limits.empty() ? DefaultLimits() : LoadLimits(a.limits);
  const FleetDb db(a.db, /*create=*/false);
  FleetAnalyser analyser(a.db, limits);
  db.ForEachUnit([&](FleetUnit&& u) { analyser.Add(std::move(u)); });
  FleetAnalysis analysis = analyser.Finish();
  if (analysis.unit_count == 0) throw util::InputError(fmt::format("{}: the fleet database holds no unit", a.db));
  analysis.serial_count = db.Totals().serials;
  for (ChartSeries& s : analysis.series) {
    if (s.station.empty()) s.histogram = db.Histogram(s.parameter);
  }
  const std::string html = RenderFleetHtml(analysis);
  std::string csv;
  if (!a.csv.empty()) {
    csv = FleetCsvHeader();
    db.ForEachUnit([&](FleetUnit&& u) {
      csv += FleetCsvRows(analysis.parameters, u, JudgeUnit(u, analysis.parameters, limits));
    });
  }
  const std::string json = a.json.empty() ? "" : util::JsonFileText(FleetJson(analysis));
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out, html);
  if (!a.csv.empty()) outputs.AddFile(a.csv, csv);
  if (!a.json.empty()) outputs.AddFile(a.json, json);
  outputs.Commit();
  const std::int64_t passed = analysis.counts.back().passed;
  fmt::print(out, "{}: {} records, {} PASS, {} FAIL, {} out-of-control signal(s)\n", a.out, analysis.unit_count,
             passed, analysis.unit_count - passed, analysis.out_of_control.size());
}

void RunFleetCheck(const std::string& path, std::ostream& out) {
  const FleetDb db(path, /*create=*/false);
  const FleetCheck c = db.Check();
  fmt::print(out, "{}: ok: schema version {}, {} record(s), {} measurement(s); SQLite's integrity check passed\n", path,
             kFleetSchemaVersion, c.units, c.measurements);
}

void RunFleetBackup(const FleetBackupRequest& a, std::ostream& out) {
  const FleetDb db(a.db, /*create=*/false);
  const std::string bytes = db.Backup();
  util::WriteFileAtomic(a.out, bytes);
  fmt::print(out, "{}: backup of {} ({} bytes)\n", a.out, a.db, bytes.size());
}

}  // namespace topocal::report

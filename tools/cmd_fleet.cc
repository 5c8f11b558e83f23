// topocal fleet: the production line's unit records in a SQLite database (report/fleet_db.h) and its fleet report
// (report/fleet_report.h). docs/fleet.md.
#include <fmt/format.h>

#include <memory>
#include <string>
#include <vector>

#include "report/acceptance.h"
#include "report/fleet_db.h"
#include "report/fleet_report.h"
#include "report/record_check.h"
#include "report/unit_record_reader.h"
#include "report/unit_record_writer.h"
#include "tools/commands.h"
#include "util/io.h"
#include "util/json_section.h"

namespace topocal::tools {
namespace {

struct IngestArgs {
  std::string db, station = "unassigned";
  std::vector<std::string> records;
  bool recompute = false;
};

struct BackupArgs {
  std::string db, out;
};

struct FleetReportArgs {
  std::string db, out, csv, json, limits;
};

void Ingest(const IngestArgs& a) {
  if (a.station.empty()) throw util::InputError("--station: must not be empty");
  // Every record is read and verified before the database is touched: one bad record refuses the batch.
  std::vector<report::UnitRecord> records;
  for (const std::string& dir : a.records) {
    if (report::IsRecordLeftover(dir)) {
      fmt::print(stderr, "{}: skipped: a staging folder a killed run left (the next run for that unit removes it)\n",
                 dir);
      continue;
    }
    records.push_back(report::ReadUnitRecord(dir));
    if (a.recompute) report::RecomputeRecordNumbers(records.back());
  }
  if (records.empty()) throw util::InputError("no unit record to ingest (every directory given was a leftover)");
  report::FleetDb db(a.db, /*create=*/true);
  const report::IngestResult r = db.Ingest(records, a.station);
  fmt::print("{}: {} record(s) added, {} already present; {} record(s) in the database\n", a.db, r.added, r.present,
             db.Totals().records);
}

// The analysis in one pass over the database (one unit in memory at a time), the histograms and the count of
// serials from SQLite; the CSV, when asked, in a second pass.
void Report(const FleetReportArgs& a) {
  const report::Limits limits = a.limits.empty() ? report::DefaultLimits() : report::LoadLimits(a.limits);
  const report::FleetDb db(a.db, /*create=*/false);
  report::FleetAnalyser analyser(a.db, limits);
  db.ForEachUnit([&](report::FleetUnit&& u) { analyser.Add(std::move(u)); });
  report::FleetAnalysis analysis = analyser.Finish();
  if (analysis.unit_count == 0) throw util::InputError(fmt::format("{}: the fleet database holds no unit", a.db));
  analysis.serial_count = db.Totals().serials;
  for (report::ChartSeries& s : analysis.series) {
    if (s.station.empty()) s.histogram = db.Histogram(s.parameter);
  }
  const std::string html = report::RenderFleetHtml(analysis);
  std::string csv;
  if (!a.csv.empty()) {
    csv = report::FleetCsvHeader();
    db.ForEachUnit([&](report::FleetUnit&& u) {
      csv += report::FleetCsvRows(analysis.parameters, u, report::JudgeUnit(u, analysis.parameters, limits));
    });
  }
  const std::string json = a.json.empty() ? "" : util::JsonFileText(report::FleetJson(analysis));
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out, html);
  if (!a.csv.empty()) outputs.AddFile(a.csv, csv);
  if (!a.json.empty()) outputs.AddFile(a.json, json);
  outputs.Commit();
  const std::int64_t passed = analysis.counts.back().passed;
  fmt::print("{}: {} records, {} PASS, {} FAIL, {} out-of-control signal(s)\n", a.out, analysis.unit_count, passed,
             analysis.unit_count - passed, analysis.out_of_control.size());
}

void Check(const std::string& path) {
  const report::FleetDb db(path, /*create=*/false);
  const report::FleetCheck c = db.Check();
  fmt::print("{}: ok: schema version {}, {} record(s), {} measurement(s); SQLite's integrity check passed\n", path,
             report::kFleetSchemaVersion, c.units, c.measurements);
}

void Backup(const BackupArgs& a) {
  const report::FleetDb db(a.db, /*create=*/false);
  const std::string bytes = db.Backup();
  util::WriteFileAtomic(a.out, bytes);
  fmt::print("{}: backup of {} ({} bytes)\n", a.out, a.db, bytes.size());
}

}  // namespace

void AddFleetCommand(CLI::App& app) {
  auto* fleet = app.add_subcommand("fleet", "The production line's unit records in a SQLite database, and its report");
  fleet->require_subcommand(1);

  auto ia = std::make_shared<IngestArgs>();
  auto* ingest = fleet->add_subcommand("ingest", "Add unit records to the fleet database (idempotent; a record whose "
                                                 "digests do not verify is refused and nothing is added)");
  ingest->add_option("--db", ia->db, "Fleet database (SQLite; created when absent)")->required();
  ingest->add_option("--station", ia->station, "Calibration station stored with the new records")
      ->capture_default_str();
  ingest->add_option("records", ia->records, "Unit record directories (units/*/)")->required();
  ingest->add_flag("--recompute", ia->recompute,
                   "Also recompute every check of each record from its files, as `topocal report` does (its Monte "
                   "Carlo again: seconds a record)");
  ingest->callback([ia] { Ingest(*ia); });

  auto ra = std::make_shared<FleetReportArgs>();
  auto* rep = fleet->add_subcommand("report", "Fleet report: distributions, control charts, units to look at");
  rep->add_option("--db", ra->db, "Fleet database")->required();
  rep->add_option("--out", ra->out, "Output HTML file")->required();
  rep->add_option("--csv", ra->csv, "Also write every unit's numbers as CSV");
  rep->add_option("--json", ra->json, "Also write the analysis as JSON");
  rep->add_option("--limits", ra->limits, "Acceptance limits (JSON, see data/limits.json); default: built in");
  rep->callback([ra] { Report(*ra); });

  auto check_db = std::make_shared<std::string>();
  auto* check = fleet->add_subcommand("check", "Check the fleet database: SQLite's integrity check, its layout and "
                                               "every stored value");
  check->add_option("--db", *check_db, "Fleet database")->required();
  check->callback([check_db] { Check(*check_db); });

  auto ba = std::make_shared<BackupArgs>();
  auto* backup = fleet->add_subcommand("backup", "Copy the fleet database consistently while it is in use (SQLite's "
                                                 "online backup), checked before it is written");
  backup->add_option("--db", ba->db, "Fleet database")->required();
  backup->add_option("--out", ba->out, "The copy (a new fleet database file)")->required();
  backup->callback([ba] { Backup(*ba); });
}

}  // namespace topocal::tools

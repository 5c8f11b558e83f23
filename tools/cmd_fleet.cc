// topocal fleet: the production line's unit records in a SQLite database and its fleet report
// (report/fleet_command.h; docs/fleet.md).
#include <memory>
#include <string>

#include "report/fleet_command.h"
#include "tools/commands.h"
#include "util/terminal_progress.h"

namespace topocal::tools {

void AddFleetCommand(CLI::App& app) {
  auto* fleet = app.add_subcommand("fleet", "The production line's unit records in a SQLite database, and its report");
  fleet->require_subcommand(1);

  auto ia = std::make_shared<report::FleetIngestRequest>();
  auto* ingest = fleet->add_subcommand("ingest", "Add unit records to the fleet database (idempotent; a record whose "
                                                 "digests do not verify is refused and nothing is added)");
  ingest->add_option("--db", ia->db, "Fleet database (SQLite; created when absent)")->required();
  ingest->add_option("--station", ia->station, "Calibration station stored with the new records")
      ->capture_default_str();
  ingest->add_option("records", ia->records, "Unit record directories (units/*/)")->required();
  ingest->add_flag("--recompute", ia->recompute,
                   "Also recompute every check of each record from its files, as `topocal report` does (its Monte "
                   "Carlo again: seconds a record)");
  ia->log = util::LogOnStderr("");
  ingest->callback([ia] { report::RunFleetIngest(*ia, std::cout); });

  auto ra = std::make_shared<report::FleetReportRequest>();
  auto* rep = fleet->add_subcommand("report", "Fleet report: distributions, control charts, units to look at");
  rep->add_option("--db", ra->db, "Fleet database")->required();
  rep->add_option("--out", ra->out, "Output HTML file")->required();
  rep->add_option("--csv", ra->csv, "Also write every unit's numbers as CSV");
  rep->add_option("--json", ra->json, "Also write the analysis as JSON");
  rep->add_option("--limits", ra->limits, "Acceptance limits (JSON, see data/limits.json); default: built in");
  rep->callback([ra] { report::RunFleetReport(*ra, std::cout); });

  auto check_db = std::make_shared<std::string>();
  auto* check = fleet->add_subcommand("check", "Check the fleet database: SQLite's integrity check, its layout and "
                                               "every stored value");
  check->add_option("--db", *check_db, "Fleet database")->required();
  check->callback([check_db] { report::RunFleetCheck(*check_db, std::cout); });

  auto ba = std::make_shared<report::FleetBackupRequest>();
  auto* backup = fleet->add_subcommand("backup", "Copy the fleet database consistently while it is in use (SQLite's "
                                                 "online backup), checked before it is written");
  backup->add_option("--db", ba->db, "Fleet database")->required();
  backup->add_option("--out", ba->out, "The copy (a new fleet database file)")->required();
  backup->callback([ba] { report::RunFleetBackup(*ba, std::cout); });
}

}  // namespace topocal::tools

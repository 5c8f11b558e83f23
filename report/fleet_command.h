#pragma once
// `topocal fleet` as library calls: the production line's unit records in a SQLite database (report/fleet_db.h),
// its fleet report (report/fleet_report.h), its check and its backup (docs/fleet.md).
#include <ostream>
#include <string>
#include <vector>

#include "util/progress_display.h"

namespace topocal::report {

struct FleetIngestRequest {
  std::string db;                      // fleet database (SQLite; created when absent)
  std::string station = "unassigned";  // calibration station stored with the new records
  std::vector<std::string> records;    // unit record directories
  bool recompute = false;              // recompute every check of each record from its files first
  util::LogLine log;                   // the staging folders of killed runs, skipped
};

struct FleetReportRequest {
  std::string db;      // fleet database
  std::string out;     // HTML report
  std::string csv;     // also every unit's numbers as CSV, when not empty
  std::string json;    // also the analysis as JSON, when not empty
  std::string limits;  // acceptance limits (JSON); empty: the built-in ones
};

struct FleetBackupRequest {
  std::string db;   // fleet database
  std::string out;  // the copy (a new fleet database file)
};

// Every record is read and verified before the database is touched: one bad record refuses the batch.
void RunFleetIngest(const FleetIngestRequest& request, std::ostream& out);
// The analysis in one pass over the database (one unit in memory at a time); the files published together.
void RunFleetReport(const FleetReportRequest& request, std::ostream& out);
// SQLite's integrity check, the layout and every stored value of the database at `db`.
void RunFleetCheck(const std::string& db, std::ostream& out);
// A consistent copy of a database in use (SQLite's online backup), checked before it is written.
void RunFleetBackup(const FleetBackupRequest& request, std::ostream& out);

}  // namespace topocal::report

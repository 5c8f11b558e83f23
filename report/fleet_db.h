#pragma once
// The production line's fleet database (docs/fleet.md): unit records ingested into SQLite, the embedded default.
//
// Schema version 3 (PRAGMA user_version = 3, PRAGMA application_id = kFleetApplicationId), STRICT tables:
//   units(id INTEGER PRIMARY KEY, serial, content_sha256 UNIQUE, unit_json_sha256, created_utc, station,
//         tool_version, model, source, ingested_utc)
//   measurements(unit_id REFERENCES units(id), parameter, value, U, PRIMARY KEY(unit_id, parameter))
// indexed by time (units), serial (units), parameter and unit (measurements), parameter and value (measurements).
// Version 2 lacked the last two indexes only: it is read as it is, and a writer adds them (a migration in one
// transaction; the rows are untouched).
// One row in `units` per record, identified by the digest of unit.json's content (UnitRecord::
// unit_json_content_sha256: the same record re-indented is the same record; ingestion is idempotent, and a unit
// calibrated again is a new row with the same serial); one row per charted number in `measurements`
// (FleetMeasurements).
//
// A ledger: every stored value is valid by construction — checked against the record's digested files
// (report/record_check.h CheckRecordedCalibration), finite, UTF-8, ISO 8601 dates; CHECK constraints hold the same
// in SQLite, and reading checks them again. A file that is damaged (SQLite's quick check), of another application,
// version or layout is refused before anything is written or read (util::InputError, exit 2).
//
// Concurrency: every write is one transaction begun with BEGIN IMMEDIATE (the write lock taken up front, so two
// writers never deadlock upgrading a read lock) under a busy timeout: processes ingesting at the same time queue,
// and each commits all of its records or none.
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "plot/svg_charts.h"
#include "report/unit_record_reader.h"

struct sqlite3;

namespace topocal::report {

inline constexpr int kFleetSchemaVersion = 3;
// 2: without the indexes by serial and by value (read as it is, migrated by a writer); 1: records identified by
// bytes, no CHECK constraints (refused).
inline constexpr int kFleetOldestReadableSchemaVersion = 2;
inline constexpr std::int32_t kFleetApplicationId = 0x54504346;  // "TPCF"
// How long a writer waits for another process's transaction before giving up (exit 1, nothing written).
inline constexpr int kFleetBusyTimeoutMs = 60000;

// The report's two queries over every unit, here so that a test can ask SQLite for their plans (docs/fleet.md):
// the units in time order by the index units_by_time, each one's measurements by their primary key (no sort);
// one parameter's values counted into bins from the index measurements_by_value alone (plot::BinValues's
// expression: ?1 parameter, ?2 bins, ?3 lowest value, ?4 bin width).
inline constexpr const char* kFleetUnitsInTimeOrderSql =
    "SELECT u.id, u.serial, u.unit_json_sha256, u.created_utc, u.station, u.tool_version, u.model, u.source, "
    "u.ingested_utc, m.parameter, m.value, m.U FROM units AS u LEFT JOIN measurements AS m "
    "ON m.unit_id = u.id ORDER BY u.created_utc, u.id";
inline constexpr const char* kFleetHistogramSql =
    "SELECT min(?2 - 1, CAST((value - ?3) / ?4 AS INTEGER)) AS bin, count(*) FROM measurements "
    "WHERE parameter = ?1 GROUP BY bin";

struct FleetMeasurement {
  std::string parameter;    // e.g. "sphere_radius_error_mm" (docs/fleet.md lists them)
  double value = 0;         // signed
  std::optional<double> U;  // expanded uncertainty, k = 2, when known
};

// The numbers of one record that the fleet view charts: calibration RMS, Seidel sigma, every fitted calibration
// parameter (calib_<name>), the reference sphere's corrected radius and power errors (U from the report's budget
// with its defaults), the paper cornea's corrected - truth of r_x, r_y, k_x, k_y.
std::vector<FleetMeasurement> FleetMeasurements(const UnitRecord& record);

struct FleetUnit {
  std::int64_t id = 0;
  std::string serial, unit_json_sha256, created_utc, station, tool_version, model, source, ingested_utc;
  std::map<std::string, FleetMeasurement> measurements;  // by parameter
};

struct FleetCheck {
  int units = 0, measurements = 0;
};

struct FleetTotals {
  std::int64_t records = 0, serials = 0;  // rows of `units`; distinct serials (a unit calibrated again is one)
};

struct IngestResult {
  int added = 0;    // new records
  int present = 0;  // already in the database (same unit.json digest): left as they were
};

class FleetDb {
 public:
  // Opens the database at `path`, creating it (and the schema) when `create` and it does not exist. Throws
  // util::InputError "PATH: problem" when it cannot be opened or created, is read-only while `create` (a writer)
  // asks for writing, is not a topocal fleet database, or has another schema version.
  FleetDb(const std::string& path, bool create);
  ~FleetDb();
  FleetDb(const FleetDb&) = delete;
  FleetDb& operator=(const FleetDb&) = delete;

  // Adds the records in one transaction: all or none. `station` is stored with each new record. Every record is
  // checked first (its calibration numbers against its calibration files, finite numbers, UTF-8 text, an ISO 8601
  // date): one that fails refuses the batch (util::InputError naming the record and key), nothing written.
  IngestResult Ingest(const std::vector<UnitRecord>& records, const std::string& station);
  // Every unit with its measurements, in order of created_utc, then id, given to `visit` one at a time (one unit
  // in memory, whatever the size of the fleet). A stored value that is not what the schema allows (written by
  // something else with SQLite's checks off) throws util::InputError "corrupt".
  void ForEachUnit(const std::function<void(FleetUnit&&)>& visit) const;
  // ForEachUnit collected (a small fleet, the Python bindings, the tests).
  std::vector<FleetUnit> Units() const;
  FleetTotals Totals() const;
  // The histogram of one parameter over every unit (plot::BinValues's bins), counted by SQLite from the index of
  // values: what the report draws, without reading the values out.
  plot::HistogramBins Histogram(const std::string& parameter) const;
  // SQLite's full integrity check, the foreign keys and every stored value; throws util::InputError "PATH:
  // corrupt: ..." at the first finding.
  FleetCheck Check() const;
  // A consistent copy of the database (SQLite's online backup API: other processes may write meanwhile), checked
  // whole, as the bytes of a database file.
  std::string Backup() const;

  const std::string& path() const { return path_; }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
};

}  // namespace topocal::report

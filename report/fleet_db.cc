#include "report/fleet_db.h"

#include <fmt/format.h>
#include <sqlite3.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <stdexcept>

#include "report/acceptance.h"
#include "report/record_check.h"
#include "util/json_section.h"
#include "util/io.h"
#include "util/utc_date.h"

namespace topocal::report {
namespace {

// STRICT tables and CHECK constraints: a value that is not a finite REAL, a negative U, an empty name or a malformed
// date cannot be stored by anyone writing through SQLite (a writer that switches the checks off is caught on
// reading, ValidUnit / ValidMeasurement).
constexpr const char* kSchemaV2 = R"sql(
CREATE TABLE units (
  id               INTEGER PRIMARY KEY,
  serial           TEXT NOT NULL CHECK (length(serial) > 0),
  content_sha256   TEXT NOT NULL UNIQUE CHECK (length(content_sha256) = 64),
  unit_json_sha256 TEXT NOT NULL CHECK (length(unit_json_sha256) = 64),
  created_utc      TEXT NOT NULL CHECK (created_utc GLOB '????-??-??T??:??:??Z'),
  station          TEXT NOT NULL CHECK (length(station) > 0),
  tool_version     TEXT NOT NULL,
  model            TEXT NOT NULL,
  source           TEXT NOT NULL,
  ingested_utc     TEXT NOT NULL CHECK (ingested_utc GLOB '????-??-??T??:??:??Z')
) STRICT;
CREATE INDEX units_by_time ON units(created_utc, id);
CREATE TABLE measurements (
  unit_id   INTEGER NOT NULL REFERENCES units(id),
  parameter TEXT NOT NULL CHECK (length(parameter) > 0),
  value     REAL NOT NULL CHECK (abs(value) <= 1.7976931348623157e308),
  U         REAL CHECK (U IS NULL OR (U >= 0 AND U <= 1.7976931348623157e308)),
  PRIMARY KEY (unit_id, parameter)
) STRICT;
CREATE INDEX measurements_by_parameter ON measurements(parameter, unit_id);
)sql";

// Version 3 adds two indexes to version 2 (docs/fleet.md "At scale"): a unit's history by serial (and the count of
// distinct serials the report states), and a parameter's values in order, which the report's histograms and each
// parameter's range read without visiting the table. A version-2 database opened by a writer gets them in one
// transaction (MigrateToV3); a reader reads it as it is.
constexpr const char* kIndexesV3 = R"sql(
CREATE INDEX units_by_serial ON units(serial, created_utc);
CREATE INDEX measurements_by_value ON measurements(parameter, value);
)sql";

// What the line is told when SQLite finds the file damaged: the database is the line's ledger, so it is never
// written into or reported from, and a backup (`topocal fleet backup`) is where it comes back from.
std::string CorruptMessage(const std::string& path, const std::string& what) {
  return fmt::format("{}: corrupt: {}; restore it from a backup (topocal fleet backup)", path, what);
}

// A failed SQLite call: a damaged or foreign file is bad input (exit 2, util::InputError), anything else (a lock held
// beyond the timeout, a full disk) a failed computation.
[[noreturn]] void FailSqlite(sqlite3* db, const std::string& path, const std::string& what) {
  const int code = sqlite3_errcode(db) & 0xff;
  if (code == SQLITE_CORRUPT) throw util::InputError(CorruptMessage(path, sqlite3_errmsg(db)));
  if (code == SQLITE_NOTADB) {
    throw util::InputError(fmt::format("{}: not a topocal fleet database ({})", path, sqlite3_errmsg(db)));
  }
  throw std::runtime_error(fmt::format("{}: SQLite {} failed: {}", path, what, sqlite3_errmsg(db)));
}

// A prepared statement, finalized on scope exit.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& path, const char* sql) : db_(db), path_(path) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) FailSqlite(db_, path_, "prepare");
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  void Text(int i, const std::string& v) { sqlite3_bind_text(stmt_, i, v.c_str(), -1, SQLITE_TRANSIENT); }
  void Double(int i, double v) { sqlite3_bind_double(stmt_, i, v); }
  void Int(int i, std::int64_t v) { sqlite3_bind_int64(stmt_, i, v); }
  void Null(int i) { sqlite3_bind_null(stmt_, i); }
  // true: a row is ready; false: done.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    FailSqlite(db_, path_, "step");
  }
  void Reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  std::string ColumnText(int i) const {
    const auto* t = sqlite3_column_text(stmt_, i);
    return t ? reinterpret_cast<const char*>(t) : "";
  }
  double ColumnDouble(int i) const { return sqlite3_column_double(stmt_, i); }
  std::int64_t ColumnInt(int i) const { return sqlite3_column_int64(stmt_, i); }
  int ColumnType(int i) const { return sqlite3_column_type(stmt_, i); }
  bool ColumnNull(int i) const { return ColumnType(i) == SQLITE_NULL; }

 private:
  sqlite3* db_;
  const std::string& path_;
  sqlite3_stmt* stmt_ = nullptr;
};

void Exec(sqlite3* db, const std::string& path, const char* sql) {
  if (sqlite3_exec(db, sql, nullptr, nullptr, nullptr) != SQLITE_OK) FailSqlite(db, path, "statement");
}

std::int64_t PragmaInt(sqlite3* db, const std::string& path, const char* pragma) {
  Statement s(db, path, pragma);
  return s.Step() ? s.ColumnInt(0) : 0;
}

// Rolls back unless committed.
class Transaction {
 public:
  Transaction(sqlite3* db, const std::string& path) : db_(db), path_(path) { Exec(db, path, "BEGIN IMMEDIATE"); }
  ~Transaction() {
    if (!done_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }
  void Commit() {
    Exec(db_, path_, "COMMIT");
    done_ = true;
  }

 private:
  sqlite3* db_;
  const std::string& path_;
  bool done_ = false;
};

// The schema objects (tables, indexes) as SQLite lists them: the layout a fleet database must have exactly.
std::vector<std::string> SchemaObjects(sqlite3* db, const std::string& path) {
  std::vector<std::string> objects;
  Statement s(db, path, "SELECT type, name, tbl_name, sql FROM sqlite_master ORDER BY type, name");
  while (s.Step()) {
    objects.push_back(fmt::format("{} {} on {}: {}", s.ColumnText(0), s.ColumnText(1), s.ColumnText(2),
                                  s.ColumnText(3)));
  }
  return objects;
}

// The layout of schema `version` (2 or 3), read back from a scratch database in memory (so the comparison does not
// depend on how SQLite stores the schema's text).
std::vector<std::string> SchemaObjectsOf(int version) {
  sqlite3* db = nullptr;
  const std::string name = "fleet schema";
  if (sqlite3_open(":memory:", &db) != SQLITE_OK) throw std::runtime_error("SQLite: cannot open a memory database");
  std::vector<std::string> out;
  try {
    Exec(db, name, kSchemaV2);
    if (version >= 3) Exec(db, name, kIndexesV3);
    out = SchemaObjects(db, name);
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  return out;
}

const std::vector<std::string>& ExpectedSchemaObjects(int version) {
  static const std::vector<std::string> v2 = SchemaObjectsOf(2), v3 = SchemaObjectsOf(3);
  return version >= 3 ? v3 : v2;
}

// PRAGMA quick_check or integrity_check: "ok", or SQLite's first finding on one line (its answer may start with a
// "*** in database main ***" line and run over many).
std::string IntegrityFinding(sqlite3* db, const std::string& path, const char* pragma) {
  Statement s(db, path, pragma);
  std::string text = s.Step() ? s.ColumnText(0) : "no answer";
  constexpr std::string_view kHeader = "*** in database main ***\n";
  if (text.rfind(kHeader, 0) == 0) text.erase(0, kHeader.size());
  text = text.substr(0, text.find('\n'));
  return text.size() > 200 ? text.substr(0, 200) + "..." : text;
}

// A record's row as the ledger accepts it: text in UTF-8, dates in ISO 8601, every number finite (and U >= 0).
void CheckLedgerRow(const UnitRecord& rec, const std::vector<FleetMeasurement>& m) {
  const std::string& at = rec.unit_json_path;
  if (!util::IsValidUtf8(rec.directory)) {
    throw util::InputError(fmt::format("{}: the record's directory name is not valid UTF-8", rec.directory));
  }
  if (!util::IsIsoUtcDate(rec.created_utc)) {
    throw util::InputError(fmt::format("{}: created_utc: '{:.40}' is not an ISO 8601 UTC date (YYYY-MM-DDTHH:MM:SSZ)",
                                       at, rec.created_utc));
  }
  for (const FleetMeasurement& x : m) {
    if (!std::isfinite(x.value) || (x.U && (!std::isfinite(*x.U) || *x.U < 0))) {
      throw util::InputError(fmt::format("{}: {}: {} (U {}) cannot be stored: not a finite number", at, x.parameter,
                                         x.value, x.U ? fmt::format("{}", *x.U) : "none"));
    }
  }
}

// The device stage's evidence (docs/fleet.md): every fitted device parameter with U = 2 sd (device_<name>), the fit's
// chi^2/dof, and the held-out ball measured through the device against its certified radius. Entries device.json
// does not hold as numbers are left out (a nominal device has no calibration block).
void AddDeviceMeasurements(const DeviceStageRecord& device, std::vector<FleetMeasurement>& m) {
  const nlohmann::json& cal = device.file.calibration;
  if (cal.is_object()) {
    if (const auto p = cal.find("parameters"); p != cal.end() && p->is_object()) {
      for (const auto& [name, e] : p->items()) {
        const auto value = e.find("value"), sd = e.find("stddev");
        if (!e.is_object() || value == e.end() || !value->is_number()) continue;
        std::optional<double> U;
        if (sd != e.end() && sd->is_number()) U = 2 * sd->get<double>();
        m.push_back({"device_" + name, value->get<double>(), U});
      }
    }
    if (const auto chi2 = cal.find("chi2_per_dof"); chi2 != cal.end() && chi2->is_number()) {
      m.push_back({"device_chi2_per_dof", chi2->get<double>(), std::nullopt});
    }
  }
  if (const auto h = device.held_out.find("device"); h != device.held_out.end() && h->second.count("radius_mm")) {
    m.push_back({"held_out_radius_error_mm", h->second.at("radius_mm") - device.held_out_radius_true_mm, std::nullopt});
  }
}

}  // namespace

std::vector<FleetMeasurement> FleetMeasurements(const UnitRecord& rec) {
  std::vector<FleetMeasurement> m;
  m.push_back({"calibration_rms_px", rec.calibration_rms_px, std::nullopt});
  if (rec.seidel_sigma_per_mm2) {
    m.push_back({"seidel_sigma_per_mm2", *rec.seidel_sigma_per_mm2,
                 2 * rec.seidel_sigma_stddev_per_mm2.value_or(0)});
  }
  for (const CalibrationParameter& p : rec.parameters) {
    if (!p.fixed) m.push_back({"calib_" + p.name, p.value, 2 * p.stddev});
  }
  // The sphere's U as the report judges it (the budget with its documented defaults).
  const Verdict v = Evaluate(rec, DefaultLimits());
  if (rec.verification) {
    for (const Check& c : v.checks) {
      if (c.id == "sphere_radius_error_mm") m.push_back({c.id, rec.verification->corrected.at("radius_error_mm"), c.U});
      if (c.id == "sphere_power_error_D") m.push_back({c.id, rec.verification->corrected.at("power_error_D"), c.U});
    }
  }
  if (rec.device) AddDeviceMeasurements(*rec.device, m);
  for (const auto& [key, name] : {std::pair{"rx_mm", "paper_rx_error_mm"}, std::pair{"ry_mm", "paper_ry_error_mm"},
                                  std::pair{"kx", "paper_kx_error"}, std::pair{"ky", "paper_ky_error"}}) {
    std::optional<double> U;
    if (rec.paper.uncertainty && rec.paper.uncertainty->quantities.count(key)) {
      U = rec.paper.uncertainty->quantities.at(key).U;
    }
    m.push_back({name, rec.paper.corrected.at(key) - rec.paper.truth.at(key), U});
  }
  return m;
}

namespace {

// Opens `path` as SQLite, nothing more (FleetDb's constructor identifies it).
sqlite3* OpenSqlite(const std::string& path, bool create) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const bool exists = fs::exists(path, ec);
  if (!exists && !create) throw util::InputError(fmt::format("{}: no such fleet database", path));
  if (exists && !fs::is_regular_file(path, ec)) throw util::InputError(fmt::format("{}: not a file", path));
  if (exists) util::NoteInput(path);  // `fleet report --out` naming the database would replace it
  const int flags = create ? (SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE) : SQLITE_OPEN_READONLY;
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db, flags, nullptr) != SQLITE_OK) {
    const std::string message = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    throw util::InputError(fmt::format("{}: cannot open the fleet database: {}", path, message));
  }
  sqlite3_busy_timeout(db, kFleetBusyTimeoutMs);
  return db;
}

struct Identity {
  std::int64_t application_id = 0, version = 0, objects = 0;
};

Identity ReadIdentity(sqlite3* db, const std::string& path) {
  // One read transaction, so one snapshot: a process creating the schema meanwhile is seen whole or not at all
  // (read one statement at a time, its tables could be seen before its application_id: "application_id 0").
  Identity id;
  try {
    Exec(db, path, "BEGIN");
    id.application_id = PragmaInt(db, path, "PRAGMA application_id");
    id.version = PragmaInt(db, path, "PRAGMA user_version");
    id.objects = PragmaInt(db, path, "SELECT count(*) FROM sqlite_master");
    Exec(db, path, "COMMIT");
  } catch (const std::runtime_error&) {
    throw util::InputError(fmt::format("{}: not a topocal fleet database ({})", path, sqlite3_errmsg(db)));
  }
  return id;
}

void CreateSchema(sqlite3* db, const std::string& path) {
  Transaction t(db, path);
  // Another process may have created the schema while this one waited for the lock.
  if (PragmaInt(db, path, "SELECT count(*) FROM sqlite_master") == 0) {
    try {
      Exec(db, path, kSchemaV2);
      Exec(db, path, kIndexesV3);
      Exec(db, path, fmt::format("PRAGMA application_id = {}; PRAGMA user_version = {}", kFleetApplicationId,
                                 kFleetSchemaVersion).c_str());
    } catch (const std::runtime_error& e) {
      throw util::InputError(fmt::format("{}: cannot create the fleet database: {}", path, sqlite3_errmsg(db)));
    }
  }
  t.Commit();
}

// Version 2 to 3: the indexes added, in one transaction (another writer may have migrated it meanwhile). The rows are
// untouched, so a version-2 database keeps every record and reads the same.
void MigrateToV3(sqlite3* db, const std::string& path) {
  Transaction t(db, path);
  if (PragmaInt(db, path, "PRAGMA user_version") == 2) {
    Exec(db, path, kIndexesV3);
    Exec(db, path, "PRAGMA user_version = 3");
  }
  t.Commit();
}

// Refuses, before anything is written or read from it, a file that is not this topocal's fleet database: another
// application's (application_id), another schema version, another layout (tables or indexes changed), a damaged
// one (SQLite's quick check).
void Identify(sqlite3* db, const std::string& path, bool create) {
  if (create && sqlite3_db_readonly(db, "main") == 1) {
    throw util::InputError(fmt::format("{}: the fleet database is read-only", path));
  }
  Identity id = ReadIdentity(db, path);
  if (id.application_id == 0 && id.version == 0 && id.objects == 0) {
    if (!create) throw util::InputError(fmt::format("{}: empty, not a topocal fleet database", path));
    CreateSchema(db, path);
    id = ReadIdentity(db, path);
  }
  if (id.application_id != kFleetApplicationId) {
    throw util::InputError(
        fmt::format("{}: not a topocal fleet database (application_id {})", path, id.application_id));
  }
  const bool readable = id.version == kFleetSchemaVersion || id.version == kFleetOldestReadableSchemaVersion;
  if (!readable) {
    throw util::InputError(fmt::format("{}: fleet database schema version {} is not supported (this topocal reads "
                                       "versions {} and {}{})",
                                       path, id.version, kFleetOldestReadableSchemaVersion, kFleetSchemaVersion,
                                       id.version < kFleetOldestReadableSchemaVersion
                                           ? "; ingest the unit records into a new database" : ""));
  }
  const std::string finding = IntegrityFinding(db, path, "PRAGMA quick_check");
  if (finding != "ok") throw util::InputError(CorruptMessage(path, "SQLite's quick check: " + finding));
  if (SchemaObjects(db, path) != ExpectedSchemaObjects(static_cast<int>(id.version))) {
    throw util::InputError(
        fmt::format("{}: not a topocal fleet database: its tables or indexes differ from schema version {}", path,
                    id.version));
  }
  if (create && id.version < kFleetSchemaVersion) MigrateToV3(db, path);
}

// Values as the ledger stores them, checked again on reading (a writer can switch SQLite's checks off):
// otherwise the database is corrupt.
void RequireStoredText(const std::string& path, std::int64_t id, const char* column, const std::string& value) {
  if (value.empty() || !util::IsValidUtf8(value)) {
    throw util::InputError(CorruptMessage(path, fmt::format("unit {}: {} is empty or not UTF-8 text", id, column)));
  }
}

FleetUnit ReadUnitRow(const Statement& s, const std::string& path) {
  FleetUnit u;
  u.id = s.ColumnInt(0);
  std::string* fields[] = {&u.serial, &u.unit_json_sha256, &u.created_utc, &u.station, &u.tool_version,
                           &u.model,  &u.source,           &u.ingested_utc};
  static constexpr const char* kNames[] = {"serial", "unit_json_sha256", "created_utc", "station", "tool_version",
                                           "model",  "source",           "ingested_utc"};
  for (int i = 0; i < 8; ++i) {
    if (s.ColumnType(i + 1) != SQLITE_TEXT) {
      throw util::InputError(CorruptMessage(path, fmt::format("unit {}: {} is not text", u.id, kNames[i])));
    }
    *fields[i] = s.ColumnText(i + 1);
    RequireStoredText(path, u.id, kNames[i], *fields[i]);
  }
  if (!util::IsIsoUtcDate(u.created_utc) || !util::IsIsoUtcDate(u.ingested_utc)) {
    throw util::InputError(CorruptMessage(path, fmt::format("unit {}: a date is not ISO 8601", u.id)));
  }
  return u;
}

// The measurement in columns `c` (parameter), c + 1 (value), c + 2 (U) of unit `unit_id`'s row.
FleetMeasurement ReadMeasurementRow(const Statement& s, const std::string& path, std::int64_t unit_id, int c) {
  FleetMeasurement m{s.ColumnText(c), s.ColumnDouble(c + 1), std::nullopt};
  const bool value_ok = s.ColumnType(c + 1) == SQLITE_FLOAT && std::isfinite(m.value);
  const bool u_ok = s.ColumnNull(c + 2) || (s.ColumnType(c + 2) == SQLITE_FLOAT &&
                                            std::isfinite(s.ColumnDouble(c + 2)) && s.ColumnDouble(c + 2) >= 0);
  if (!value_ok || !u_ok || m.parameter.empty() || !util::IsValidUtf8(m.parameter)) {
    throw util::InputError(CorruptMessage(
        path, fmt::format("unit {}: measurement '{:.40}' is not a finite number with a U >= 0", unit_id,
                          util::IsValidUtf8(m.parameter) ? m.parameter : std::string("?"))));
  }
  if (!s.ColumnNull(c + 2)) m.U = s.ColumnDouble(c + 2);
  return m;
}

}  // namespace

FleetDb::FleetDb(const std::string& path, bool create) : path_(path) {
  db_ = OpenSqlite(path, create);
  try {
    Identify(db_, path, create);
  } catch (...) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw;
  }
}

FleetDb::~FleetDb() { sqlite3_close(db_); }

IngestResult FleetDb::Ingest(const std::vector<UnitRecord>& records, const std::string& station) {
  // Every record is checked before the transaction begins: one that the ledger cannot hold refuses the batch.
  if (station.empty() || !util::IsValidUtf8(station)) {
    throw util::InputError("--station: must be non-empty UTF-8 text");
  }
  std::vector<std::vector<FleetMeasurement>> measurements;
  for (const UnitRecord& rec : records) {
    CheckRecordedCalibration(rec);
    measurements.push_back(FleetMeasurements(rec));
    CheckLedgerRow(rec, measurements.back());
  }
  IngestResult result;
  const std::string now = util::FileDateUtc();
  Transaction t(db_, path_);
  Statement find(db_, path_, "SELECT id FROM units WHERE content_sha256 = ?1");
  Statement unit(db_, path_,
                 "INSERT INTO units (serial, content_sha256, unit_json_sha256, created_utc, station, tool_version, "
                 "model, source, ingested_utc) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)");
  Statement meas(db_, path_, "INSERT INTO measurements (unit_id, parameter, value, U) VALUES (?1, ?2, ?3, ?4)");
  for (std::size_t r = 0; r < records.size(); ++r) {
    const UnitRecord& rec = records[r];
    find.Text(1, rec.unit_json_content_sha256);
    const bool present = find.Step();
    find.Reset();
    if (present) {
      ++result.present;
      continue;
    }
    int column = 1;
    for (const std::string* v : {&rec.serial, &rec.unit_json_content_sha256, &rec.unit_json_sha256,
                                 &rec.created_utc, &station, &rec.tool_version, &rec.settings_model, &rec.directory,
                                 &now}) {
      unit.Text(column++, *v);
    }
    unit.Step();
    unit.Reset();
    const std::int64_t id = sqlite3_last_insert_rowid(db_);
    for (const FleetMeasurement& m : measurements[r]) {
      meas.Int(1, id);
      meas.Text(2, m.parameter);
      meas.Double(3, m.value);
      if (m.U) meas.Double(4, *m.U);
      else meas.Null(4);
      meas.Step();
      meas.Reset();
    }
    ++result.added;
  }
  t.Commit();
  return result;
}

void FleetDb::ForEachUnit(const std::function<void(FleetUnit&&)>& visit) const {
  // One pass in time order (the units by units_by_time, each one's measurements by their primary key): one unit in
  // memory at a time. A measurement whose unit is not there is not joined; `fleet check` names it.
  Statement s(db_, path_, kFleetUnitsInTimeOrderSql);
  std::optional<FleetUnit> unit;
  while (s.Step()) {
    if (!unit || unit->id != s.ColumnInt(0)) {
      if (unit) visit(std::move(*unit));
      unit = ReadUnitRow(s, path_);
    }
    if (s.ColumnNull(9)) continue;  // a unit without measurements
    FleetMeasurement m = ReadMeasurementRow(s, path_, unit->id, 9);
    unit->measurements[m.parameter] = std::move(m);
  }
  if (unit) visit(std::move(*unit));
}

std::vector<FleetUnit> FleetDb::Units() const {
  std::vector<FleetUnit> units;
  ForEachUnit([&](FleetUnit&& u) { units.push_back(std::move(u)); });
  return units;
}

FleetTotals FleetDb::Totals() const {
  Statement s(db_, path_, "SELECT count(*), count(DISTINCT serial) FROM units");
  FleetTotals t;
  if (s.Step()) {
    t.records = s.ColumnInt(0);
    t.serials = s.ColumnInt(1);
  }
  return t;
}

plot::HistogramBins FleetDb::Histogram(const std::string& parameter) const {
  // Both queries read the index measurements_by_value alone (the rows of the table are not visited).
  plot::HistogramBins h;
  {
    Statement range(db_, path_, "SELECT count(*), min(value), max(value) FROM measurements WHERE parameter = ?1");
    range.Text(1, parameter);
    if (!range.Step() || range.ColumnInt(0) == 0) return h;
    h.n = range.ColumnInt(0);
    h.lo = range.ColumnDouble(1);
    h.hi = range.ColumnDouble(2);
  }
  const int bins = plot::HistogramBinCount(static_cast<std::size_t>(h.n));
  h.counts.assign(bins, 0);
  const double bw = (h.hi - h.lo) / bins;
  if (!(bw > 0)) {
    h.counts[bins / 2] = h.n;
    return h;
  }
  // plot::BinValues's expression, evaluated by SQLite in the same double arithmetic (CAST truncates as int() does).
  Statement s(db_, path_, kFleetHistogramSql);
  s.Text(1, parameter);
  s.Int(2, bins);
  s.Double(3, h.lo);
  s.Double(4, bw);
  while (s.Step()) {
    const std::int64_t bin = s.ColumnInt(0);
    if (bin >= 0 && bin < bins) h.counts[static_cast<std::size_t>(bin)] += s.ColumnInt(1);
  }
  return h;
}

FleetCheck FleetDb::Check() const {
  const std::string finding = IntegrityFinding(db_, path_, "PRAGMA integrity_check");
  if (finding != "ok") throw util::InputError(CorruptMessage(path_, "SQLite's integrity check: " + finding));
  {
    Statement fk(db_, path_, "PRAGMA foreign_key_check");
    if (fk.Step()) {
      throw util::InputError(CorruptMessage(path_, fmt::format("table {} row {} refers to a unit that is not there",
                                                               fk.ColumnText(0), fk.ColumnInt(1))));
    }
  }
  FleetCheck check;
  const std::vector<FleetUnit> units = Units();  // every stored value valid
  check.units = static_cast<int>(units.size());
  for (const FleetUnit& u : units) check.measurements += static_cast<int>(u.measurements.size());
  return check;
}

std::string FleetDb::Backup() const {
  // SQLite's online backup into a database in memory (a consistent snapshot, taken under a read lock, whatever
  // other processes write meanwhile), checked, then serialised: the caller publishes the bytes as one file.
  sqlite3* copy = nullptr;
  if (sqlite3_open(":memory:", &copy) != SQLITE_OK) throw std::runtime_error("SQLite: cannot open a memory database");
  struct Close {
    sqlite3* db;
    ~Close() { sqlite3_close(db); }
  } close{copy};
  sqlite3_backup* b = sqlite3_backup_init(copy, "main", db_, "main");
  if (b == nullptr) FailSqlite(copy, path_, "backup");
  const int rc = sqlite3_backup_step(b, -1);
  sqlite3_backup_finish(b);
  if (rc != SQLITE_DONE) FailSqlite(copy, path_, "backup");
  const std::string finding = IntegrityFinding(copy, path_, "PRAGMA integrity_check");
  if (finding != "ok") throw util::InputError(CorruptMessage(path_, "SQLite's integrity check: " + finding));
  sqlite3_int64 size = 0;
  unsigned char* bytes = sqlite3_serialize(copy, "main", &size, 0);
  if (bytes == nullptr) throw std::runtime_error(fmt::format("{}: SQLite could not serialise the backup", path_));
  std::string out(reinterpret_cast<const char*>(bytes), static_cast<std::size_t>(size));
  sqlite3_free(bytes);
  return out;
}

}  // namespace topocal::report

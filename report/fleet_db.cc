#include "report/fleet_db.h"

#include <fmt/format.h>
#include <sqlite3.h>

#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "report/acceptance.h"
#include "util/io.h"
#include "util/utc_date.h"

namespace topocal::report {
namespace {

constexpr const char* kSchema = R"sql(
CREATE TABLE units (
  id               INTEGER PRIMARY KEY,
  serial           TEXT NOT NULL,
  unit_json_sha256 TEXT NOT NULL UNIQUE,
  created_utc      TEXT NOT NULL,
  station          TEXT NOT NULL,
  tool_version     TEXT NOT NULL,
  model            TEXT NOT NULL,
  source           TEXT NOT NULL,
  ingested_utc     TEXT NOT NULL
);
CREATE INDEX units_by_time ON units(created_utc, id);
CREATE TABLE measurements (
  unit_id   INTEGER NOT NULL REFERENCES units(id),
  parameter TEXT NOT NULL,
  value     REAL NOT NULL,
  U         REAL,
  PRIMARY KEY (unit_id, parameter)
);
)sql";

// A prepared statement, finalized on scope exit.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& path, const char* sql) : db_(db), path_(path) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) Fail("prepare");
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
    Fail("step");
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
  bool ColumnNull(int i) const { return sqlite3_column_type(stmt_, i) == SQLITE_NULL; }

 private:
  [[noreturn]] void Fail(const char* what) const {
    throw std::runtime_error(fmt::format("{}: SQLite {} failed: {}", path_, what, sqlite3_errmsg(db_)));
  }
  sqlite3* db_;
  const std::string& path_;
  sqlite3_stmt* stmt_ = nullptr;
};

void Exec(sqlite3* db, const std::string& path, const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string message = err ? err : sqlite3_errmsg(db);
    sqlite3_free(err);
    throw std::runtime_error(fmt::format("{}: {}", path, message));
  }
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

FleetDb::FleetDb(const std::string& path, bool create) : path_(path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const bool exists = fs::exists(path, ec);
  if (!exists && !create) throw util::InputError(fmt::format("{}: no such fleet database", path));
  if (exists && !fs::is_regular_file(path, ec)) throw util::InputError(fmt::format("{}: not a file", path));
  if (exists) util::NoteInput(path);  // `fleet report --out` naming the database would replace it
  const int flags = create ? (SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE) : SQLITE_OPEN_READONLY;
  if (sqlite3_open_v2(path.c_str(), &db_, flags, nullptr) != SQLITE_OK) {
    const std::string message = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    throw util::InputError(fmt::format("{}: cannot open the fleet database: {}", path, message));
  }
  sqlite3_busy_timeout(db_, kFleetBusyTimeoutMs);
  // Until the database is known to be a fleet database, any exception closes it (and passes on unchanged).
  struct CloseUnlessKept {
    sqlite3** db;
    bool keep = false;
    ~CloseUnlessKept() {
      if (keep) return;
      sqlite3_close(*db);
      *db = nullptr;
    }
  } guard{&db_};
  {
    if (create && sqlite3_db_readonly(db_, "main") == 1) {
      throw util::InputError(fmt::format("{}: the fleet database is read-only", path));
    }
    // Identify before anything else: a file that is not SQLite, or another application's database, or another
    // schema version is refused without being changed.
    std::int64_t app = 0, version = 0, tables = 0;
    try {
      // One read transaction, so one snapshot: a process creating the schema meanwhile is seen whole or not at all
      // (read one statement at a time, its tables could be seen before its application_id: "application_id 0").
      Exec(db_, path, "BEGIN");
      app = PragmaInt(db_, path, "PRAGMA application_id");
      version = PragmaInt(db_, path, "PRAGMA user_version");
      tables = PragmaInt(db_, path, "SELECT count(*) FROM sqlite_master");
      Exec(db_, path, "COMMIT");
    } catch (const std::runtime_error& e) {
      throw util::InputError(fmt::format("{}: not a topocal fleet database ({})", path, sqlite3_errmsg(db_)));
    }
    if (app == 0 && version == 0 && tables == 0) {
      if (!create) throw util::InputError(fmt::format("{}: empty, not a topocal fleet database", path));
      Transaction t(db_, path);
      // Another process may have created the schema while this one waited for the lock.
      if (PragmaInt(db_, path, "SELECT count(*) FROM sqlite_master") == 0) {
        try {
          Exec(db_, path, kSchema);
          Exec(db_, path, fmt::format("PRAGMA application_id = {}; PRAGMA user_version = {}", kFleetApplicationId,
                                      kFleetSchemaVersion).c_str());
        } catch (const std::runtime_error& e) {
          throw util::InputError(fmt::format("{}: cannot create the fleet database: {}", path, sqlite3_errmsg(db_)));
        }
      }
      t.Commit();
      app = PragmaInt(db_, path, "PRAGMA application_id");
      version = PragmaInt(db_, path, "PRAGMA user_version");
    }
    if (app != kFleetApplicationId) {
      throw util::InputError(fmt::format("{}: not a topocal fleet database (application_id {})", path, app));
    }
    if (version != kFleetSchemaVersion) {
      throw util::InputError(
          fmt::format("{}: fleet database schema version {} is not supported (this topocal reads "
                      "version {})",
                      path, version, kFleetSchemaVersion));
    }
  }
  guard.keep = true;
}

FleetDb::~FleetDb() { sqlite3_close(db_); }

IngestResult FleetDb::Ingest(const std::vector<UnitRecord>& records, const std::string& station) {
  IngestResult result;
  const std::string now = util::FileDateUtc();
  Transaction t(db_, path_);
  Statement find(db_, path_, "SELECT id FROM units WHERE unit_json_sha256 = ?1");
  Statement unit(db_, path_,
                 "INSERT INTO units (serial, unit_json_sha256, created_utc, station, tool_version, model, source, "
                 "ingested_utc) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
  Statement meas(db_, path_, "INSERT INTO measurements (unit_id, parameter, value, U) VALUES (?1, ?2, ?3, ?4)");
  for (const UnitRecord& rec : records) {
    find.Text(1, rec.unit_json_sha256);
    const bool present = find.Step();
    find.Reset();
    if (present) {
      ++result.present;
      continue;
    }
    unit.Text(1, rec.serial);
    unit.Text(2, rec.unit_json_sha256);
    unit.Text(3, rec.created_utc);
    unit.Text(4, station);
    unit.Text(5, rec.tool_version);
    unit.Text(6, rec.settings_model);
    unit.Text(7, rec.directory);
    unit.Text(8, now);
    unit.Step();
    unit.Reset();
    const std::int64_t id = sqlite3_last_insert_rowid(db_);
    for (const FleetMeasurement& m : FleetMeasurements(rec)) {
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

std::vector<FleetUnit> FleetDb::Units() const {
  std::vector<FleetUnit> units;
  std::map<std::int64_t, std::size_t> index;
  {
    Statement s(db_, path_,
                "SELECT id, serial, unit_json_sha256, created_utc, station, tool_version, model, source, ingested_utc "
                "FROM units ORDER BY created_utc, id");
    while (s.Step()) {
      FleetUnit u;
      u.id = s.ColumnInt(0);
      u.serial = s.ColumnText(1);
      u.unit_json_sha256 = s.ColumnText(2);
      u.created_utc = s.ColumnText(3);
      u.station = s.ColumnText(4);
      u.tool_version = s.ColumnText(5);
      u.model = s.ColumnText(6);
      u.source = s.ColumnText(7);
      u.ingested_utc = s.ColumnText(8);
      index[u.id] = units.size();
      units.push_back(std::move(u));
    }
  }
  Statement s(db_, path_, "SELECT unit_id, parameter, value, U FROM measurements");
  while (s.Step()) {
    const auto it = index.find(s.ColumnInt(0));
    if (it == index.end()) continue;
    FleetMeasurement m{s.ColumnText(1), s.ColumnDouble(2), std::nullopt};
    if (!s.ColumnNull(3)) m.U = s.ColumnDouble(3);
    units[it->second].measurements[m.parameter] = m;
  }
  return units;
}

}  // namespace topocal::report

// Fuzz target: a fleet database (report/fleet_db.h) and everything `topocal fleet report` and `fleet check` do with
// it: Units(), the fleet analysis and its HTML/CSV/JSON renderings (every plot helper bounded whatever the stored
// values), Check() and Backup(). Two kinds of input:
//  - the bytes of a database file ("SQLite format 3" first): opening runs SQLite's quick check and compares the
//    layout before anything is read;
//  - anything else is a recipe of units written into a fresh database with SQLite's CHECK constraints switched off
//    (what another program could do), so that values byte-level mutations of a file never reach — identical records,
//    1e308 beside ordinary values, subnormals, infinities, negative U, dates like 2026-13-45, a station of invalid
//    UTF-8 — reach the reader's own checks and, when they pass, the analysis and the charts. Per unit: one byte
//    (bits 0-2: measurements 0-7; bit 3: station LINE-B, not LINE-A; bits 4-7: N, the month 1 + N % 12, except
//    N = 15: month 13, and N = 14 with bit 3: a station starting with the byte 0xFF), then per
//    measurement one byte (a parameter of FleetMeasurements' list, or an unknown one), 8 bytes of value and 8 of U
//    (raw IEEE doubles; U NULL when its first byte is 0xFF).
// Refusals must be util::InputError; anything else (a crash, a sanitizer report, another exception, a hang or an
// unbounded allocation in a chart) is a defect.
#include <sqlite3.h>

#include <cstring>
#include <filesystem>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "fuzz/fuzz_input.h"
#include "report/acceptance.h"
#include "report/fleet_db.h"
#include "report/fleet_report.h"
#include "util/json_section.h"

namespace {

namespace fs = std::filesystem;

// A few parameters the fleet stores (docs/fleet.md), and one it does not know.
constexpr const char* kParameters[] = {"calibration_rms_px",  "sphere_radius_error_mm", "sphere_power_error_D",
                                       "calib_k1",            "calib_k2",               "paper_kx_error",
                                       "paper_rx_error_mm",   "not_a_parameter"};

struct Reader {
  const uint8_t* data;
  size_t size, at = 0;
  bool Has(size_t n) const { return at + n <= size; }
  uint8_t Byte() { return Has(1) ? data[at++] : 0; }
  double Double() {
    double v = 0;
    if (Has(8)) std::memcpy(&v, data + at, 8);
    at += Has(8) ? 8 : size - at;
    return v;
  }
};

void Exec(sqlite3* db, const std::string& sql) { sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr); }

// Writes the recipe's units into a fresh database at `path` (errors of single inserts ignored: NOT NULL and the
// primary key still hold with the checks off).
void WriteRecipe(const std::string& path, const uint8_t* data, size_t size) {
  { topocal::report::FleetDb create(path, true); }
  sqlite3* db = nullptr;
  if (sqlite3_open(path.c_str(), &db) != SQLITE_OK) {
    sqlite3_close(db);
    return;
  }
  Exec(db, "PRAGMA ignore_check_constraints = ON; BEGIN;");
  Reader in{data, size};
  sqlite3_stmt* unit = nullptr;
  sqlite3_stmt* meas = nullptr;
  sqlite3_prepare_v2(db,
                     "INSERT INTO units (id, serial, content_sha256, unit_json_sha256, created_utc, station, "
                     "tool_version, model, source, ingested_utc) VALUES (?, ?, ?, ?, ?, ?, 'topocal 0', 'seidel', "
                     "'fuzz', '2026-12-06T00:00:00Z')",
                     -1, &unit, nullptr);
  sqlite3_prepare_v2(db, "INSERT INTO measurements (unit_id, parameter, value, U) VALUES (?, ?, ?, ?)", -1, &meas,
                     nullptr);
  for (int id = 1; in.Has(1) && id <= 200; ++id) {
    const uint8_t head = in.Byte();
    const std::string serial = fmt::format("SN-{:04}", id);
    const std::string digest = fmt::format("{:064x}", id);
    const int nibble = head >> 4;
    const std::string date = fmt::format("2026-{:02}-{:02}T08:00:00Z", nibble == 15 ? 13 : 1 + nibble % 12, 1 + id % 28);
    const std::string station = !(head & 8) ? "LINE-A" : nibble == 14 ? "\xff-LINE" : "LINE-B";
    sqlite3_reset(unit);
    sqlite3_bind_int64(unit, 1, id);
    sqlite3_bind_text(unit, 2, serial.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(unit, 3, digest.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(unit, 4, digest.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(unit, 5, date.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(unit, 6, station.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_step(unit);
    for (int m = 0, n = head & 7; m < n; ++m) {
      const char* parameter = kParameters[in.Byte() % (sizeof(kParameters) / sizeof(kParameters[0]))];
      const double value = in.Double();
      const bool u_null = in.Has(1) && in.data[in.at] == 0xFF;
      const double u = in.Double();
      sqlite3_reset(meas);
      sqlite3_bind_int64(meas, 1, id);
      sqlite3_bind_text(meas, 2, parameter, -1, SQLITE_STATIC);
      sqlite3_bind_double(meas, 3, value);
      if (u_null) {
        sqlite3_bind_null(meas, 4);
      } else {
        sqlite3_bind_double(meas, 4, u);
      }
      sqlite3_step(meas);
    }
  }
  sqlite3_finalize(unit);
  sqlite3_finalize(meas);
  Exec(db, "COMMIT;");
  sqlite3_close(db);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = (topocal::fuzz::ScratchDir() / "fleet.sqlite").string();
  // SQLite's journal of an earlier input must not be replayed into this one.
  for (const char* suffix : {"", "-journal", "-wal", "-shm"}) fs::remove(path + suffix);
  static constexpr char kMagic[] = "SQLite format 3";
  const bool file = size >= sizeof(kMagic) - 1 && std::memcmp(data, kMagic, sizeof(kMagic) - 1) == 0;
  if (file) {
    topocal::fuzz::InputFile("fleet.sqlite", data, size);
  } else {
    WriteRecipe(path, data, size);
  }
  std::optional<nlohmann::json> report;
  try {
    const topocal::report::FleetDb db(path, false);
    const auto analysis = topocal::report::AnalyseFleet(path, db.Units(), topocal::report::DefaultLimits());
    (void)topocal::report::RenderFleetHtml(analysis);
    (void)topocal::report::FleetCsv(analysis);
    report = topocal::report::FleetJson(analysis);
    (void)db.Check();
    (void)db.Backup();
  } catch (const topocal::util::InputError&) {
  }
  // What `fleet report --json` writes: a NaN or an infinity (null in the JSON) is a defect, thrown uncaught.
  if (report) topocal::util::RequireFiniteNumbers(*report);
  return 0;
}

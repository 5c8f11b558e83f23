// The fleet view end to end: a generated line of unit records (tests/report/fleet_fixture.h, written through the
// record writer), `topocal fleet ingest` into SQLite - idempotent, all or nothing, concurrent processes - and
// `topocal fleet report` as HTML, CSV and JSON, rendered by headless Chromium.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <set>

#include "report/fleet_db.h"
#include "report/fleet_report.h"
#include "report/unit_record_reader.h"
#include "tests/cli_harness.h"
#include "tests/report/chromium.h"
#include "tests/report/fleet_fixture.h"
#include "tests/report/record_fixture.h"
#include "util/io.h"
#include "util/sha256.h"

namespace topocal::report {
namespace {

namespace fs = std::filesystem;
using testing::FreshDir;
using topocal::testing_cli::RunTopocal;

// The generated line: three stations of 20 units each (>= 50 records), station C's sphere radius error drifting
// from its 11th unit on by 1.5 um per unit (0.75 sigma of the line's scatter), A and B stable.
constexpr int kUnitsPerStation = 20;
constexpr int kDriftFrom = 10;
constexpr double kDriftMmPerUnit = 0.0015;

class FleetTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    work_ = new std::string(FreshDir("fleet"));
    const calib::CalibrationResult cal = testing::FixtureCalibration();
    int station = 0;
    for (const char* name : {"A", "B", "C"}) {
      const auto line = testing::GenerateLine(std::string("SN-") + name, kUnitsPerStation, 100 + station,
                                              std::string(name) == "C" ? kDriftFrom : -1, kDriftMmPerUnit, station);
      for (const auto& u : line) testing::WriteLineUnit(Dir(name) + "/" + u.serial, cal, u);
      ++station;
    }
  }
  static void TearDownTestSuite() {
    // TOPOCAL_KEEP_FLEET=1 keeps the generated line, its databases and reports (to look at them).
    const char* keep = std::getenv("TOPOCAL_KEEP_FLEET");
    if (!::testing::UnitTest::GetInstance()->Failed() && !(keep && *keep)) fs::remove_all(*work_);
    delete work_;
  }
  static std::string Dir(const std::string& station) { return *work_ + "/line-" + station; }
  static std::string Db(const std::string& name) { return *work_ + "/" + name + ".sqlite"; }
  static std::string Ingest(const std::string& db, const std::string& station, const std::string& extra = "") {
    return "fleet ingest --db " + db + " --station LINE-" + station + " " + Dir(station) + "/*/" + extra;
  }
  static int CountUnits(const std::string& db) { return static_cast<int>(FleetDb(db, false).Units().size()); }
  static std::string* work_;
};
std::string* FleetTest::work_ = nullptr;

TEST_F(FleetTest, TheGeneratedRecordsAreValidRecords) {
  // Written through the record writer: each one reads back with every digest verified.
  std::set<std::string> seen;
  for (const auto& e : fs::directory_iterator(Dir("A"))) {
    const UnitRecord r = ReadUnitRecord(e.path().string());
    EXPECT_EQ(r.files.size(), 2u);  // calibration.yaml, residuals.csv
    seen.insert(r.unit_json_sha256);
  }
  EXPECT_EQ(seen.size(), static_cast<std::size_t>(kUnitsPerStation));  // all different
}

TEST_F(FleetTest, IngestionIsIdempotentAndTheReportFlagsTheDriftingStation) {
  const std::string db = Db("line");
  for (const char* s : {"A", "B", "C"}) {
    const auto run = RunTopocal(Ingest(db, s));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("20 record(s) added, 0 already present"), std::string::npos) << run.output;
  }
  ASSERT_EQ(CountUnits(db), 3 * kUnitsPerStation);
  const std::string before = util::Sha256HexOfFile(db);
  // Again: nothing added, nothing changed.
  const auto again = RunTopocal(Ingest(db, "A") + " " + Dir("B") + "/*/");
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find("0 record(s) added, 40 already present; 60 record(s)"), std::string::npos) << again.output;
  EXPECT_EQ(util::Sha256HexOfFile(db), before);

  const std::string html = *work_ + "/fleet.html", csv = *work_ + "/fleet.csv", js = *work_ + "/fleet.json";
  const auto rep = RunTopocal("fleet report --db " + db + " --out " + html + " --csv " + csv + " --json " + js);
  ASSERT_EQ(rep.exit_code, 0) << rep.output;
  const auto j = nlohmann::json::parse(util::ReadFile(js));
  EXPECT_EQ(j.at("format"), "topocal-fleet-report");
  EXPECT_EQ(j.at("units").size(), 60u);
  // The drifting station's sphere radius chart has signals at the drifting units; the stable stations' do not.
  std::map<std::string, int> signals_by_chart;
  for (const auto& c : j.at("charts")) {
    if (c.at("parameter") != "sphere_radius_error_mm" || c.at("station").is_null()) continue;
    signals_by_chart[c.at("station").get<std::string>()] = static_cast<int>(c.at("signals").size());
    if (c.at("station") == "LINE-C") {
      bool late = false;
      for (const auto& s : c.at("signals")) late = late || s.at("serial").get<std::string>() > "SN-C-0010";
      EXPECT_TRUE(late) << c.dump();
    }
  }
  EXPECT_GT(signals_by_chart["LINE-C"], 0);
  EXPECT_EQ(signals_by_chart["LINE-A"], 0);
  EXPECT_EQ(signals_by_chart["LINE-B"], 0);
  // Out-of-control units are listed on the page, by serial.
  const std::string page = util::ReadFile(html);
  EXPECT_NE(page.find("data-units=\"60\""), std::string::npos);
  EXPECT_NE(page.find("<tr data-serial=\"SN-C-00"), std::string::npos);
  EXPECT_EQ(page.find("data-parameter=\"sphere_radius_error_mm\"><td>SN-A"), std::string::npos);
  // CSV: a header and one row per unit and parameter.
  const std::string table = util::ReadFile(csv);
  EXPECT_EQ(table.rfind("serial,unit_json_sha256,created_utc,station,parameter,value,U,limit,unit_verdict\n", 0), 0u);
  EXPECT_NE(table.find("SN-C-0020,"), std::string::npos);
  // Same database, same bytes.
  const std::string first = page;
  ASSERT_EQ(RunTopocal("fleet report --db " + db + " --out " + html).exit_code, 0);
  EXPECT_EQ(util::ReadFile(html), first);
}

TEST_F(FleetTest, ConcurrentProcessesLoseNothing) {
  // Six processes at once, two per station (each station's records ingested twice, racing): every record exactly
  // once, every process succeeds.
  const std::string db = Db("concurrent");
  const std::string exe = TOPOCAL_EXE;
  std::string cmd = "(";
  for (int k = 0; k < 2; ++k) {
    for (const char* s : {"A", "B", "C"}) {
      cmd += exe + " " + Ingest(db, s) + fmt::format(" > {}/ingest-{}-{}.log 2>&1 || echo FAILED-{}-{} & ", *work_, s, k, s, k);
    }
  }
  cmd += "wait)";
  const testing::ShellRun run = testing::Shell(cmd);
  EXPECT_EQ(run.output.find("FAILED"), std::string::npos) << run.output;
  EXPECT_EQ(CountUnits(db), 3 * kUnitsPerStation);
  int added = 0;
  for (const char* s : {"A", "B", "C"}) {
    for (int k = 0; k < 2; ++k) {
      const std::string log = util::ReadFile(fmt::format("{}/ingest-{}-{}.log", *work_, s, k));
      int n = 0;
      ASSERT_EQ(std::sscanf(log.substr(log.find(": ") + 2).c_str(), "%d", &n), 1) << log;
      added += n;
    }
  }
  EXPECT_EQ(added, 3 * kUnitsPerStation);  // each record added by exactly one process
}

// One line, exit 2, and the database as it was.
void ExpectRefused(const std::string& args, const std::string& expected, const std::string& db) {
  const std::string before = fs::exists(db) ? util::Sha256HexOfFile(db) : "";
  const auto run = RunTopocal(args);
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find(expected), std::string::npos) << run.output;
  EXPECT_EQ(std::count(run.output.begin(), run.output.end(), '\n'), 1) << run.output;
  EXPECT_EQ(fs::exists(db) ? util::Sha256HexOfFile(db) : "", before);
}

TEST_F(FleetTest, BadInputIsRefusedAndTheDatabaseKeepsEverything) {
  const std::string db = Db("bad");
  ASSERT_EQ(RunTopocal(Ingest(db, "A")).exit_code, 0);
  // A tampered record (a file changed after it was written): refused, and with it the whole batch.
  const std::string bad = *work_ + "/tampered";
  fs::create_directories(bad);
  fs::copy(Dir("B") + "/SN-B-0001", bad + "/SN-B-0001", fs::copy_options::recursive);
  std::ofstream(bad + "/SN-B-0001/residuals.csv", std::ios::app) << "0,views/v1.png,999,1,1,0,0,0\n";
  ExpectRefused(Ingest(db, "B") + " " + bad + "/SN-B-0001", "residuals.csv: SHA-256", db);
  // A corrupt record.
  fs::copy(Dir("B") + "/SN-B-0002", bad + "/SN-B-0002", fs::copy_options::recursive);
  util::WriteFileAtomic(bad + "/SN-B-0002/unit.json", "{\"format\": ");
  ExpectRefused("fleet ingest --db " + db + " " + bad + "/SN-B-0002", "unit.json: not valid JSON", db);
  EXPECT_EQ(CountUnits(db), kUnitsPerStation);
  // Another schema version: neither ingested into nor reported.
  const std::string v2 = Db("v2");
  sqlite3* h = nullptr;
  ASSERT_EQ(sqlite3_open(v2.c_str(), &h), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(h, fmt::format("CREATE TABLE units(x); PRAGMA application_id = {}; PRAGMA user_version = 4",
                                        kFleetApplicationId).c_str(),
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(h);
  ExpectRefused(Ingest(v2, "A"), "schema version 4 is not supported (this topocal reads versions 2 and 3)", v2);
  ExpectRefused("fleet report --db " + v2 + " --out " + *work_ + "/v2.html", "schema version 4", v2);
  EXPECT_FALSE(fs::exists(*work_ + "/v2.html"));
  // Not a database at all; an unwritable path; a directory.
  const std::string text = *work_ + "/not-a-db.sqlite";
  util::WriteFileAtomic(text, "hello, this is not SQLite, but long enough to look like a header of one.......\n");
  ExpectRefused(Ingest(text, "A"), "not a topocal fleet database", text);
  ExpectRefused(Ingest(*work_ + "/no/such/dir/fleet.sqlite", "A"), "cannot open the fleet database", "");
  ExpectRefused(Ingest(*work_, "A"), "not a file", "");
  ExpectRefused("fleet report --db " + *work_ + "/absent.sqlite --out " + *work_ + "/x.html", "no such fleet database",
                "");
}

// Runs SQL on a database as another program would (SQLite's own checks switched off when asked).
void ExecSql(const std::string& db, const std::string& sql) {
  sqlite3* h = nullptr;
  ASSERT_EQ(sqlite3_open(db.c_str(), &h), SQLITE_OK);
  char* err = nullptr;
  EXPECT_EQ(sqlite3_exec(h, sql.c_str(), nullptr, nullptr, &err), SQLITE_OK) << (err ? err : "");
  sqlite3_free(err);
  sqlite3_close(h);
}

// A record copied to `dir` with `edit` applied to its unit.json (which no digest covers: the ledger's own checks
// must catch what the edit does).
std::string EditedRecord(const std::string& from, const std::string& dir,
                         const std::function<void(nlohmann::json&)>& edit, int indent = -1) {
  fs::remove_all(dir);
  fs::create_directories(fs::path(dir).parent_path());
  fs::copy(from, dir, fs::copy_options::recursive);
  auto j = nlohmann::json::parse(util::ReadFile(dir + "/unit.json"));
  edit(j);
  util::WriteFileAtomic(dir + "/unit.json", j.dump(indent) + "\n");
  return dir;
}

TEST_F(FleetTest, TheLedgerHoldsOnlyValuesItCanStand) {
  const std::string db = Db("ledger");
  ASSERT_EQ(RunTopocal(Ingest(db, "A")).exit_code, 0);
  const std::string rec = Dir("B") + "/SN-B-0001", edits = *work_ + "/edits";
  // A standard deviation of 1e308 in unit.json (was stored as U = inf, then written as `inf` in the CSV).
  const std::string huge = EditedRecord(rec, edits + "/huge", [](nlohmann::json& j) {
    for (auto& p : j["calibration"]["parameters"]) {
      if (p["name"] == "k1") p["stddev"] = 1e308;
    }
  });
  ExpectRefused("fleet ingest --db " + db + " " + huge,
                "calibration.parameters[k1].stddev: recorded 1e+308, calibration.yaml says", db);
  // A recorded RMS that residuals.csv does not give.
  const std::string rms = EditedRecord(rec, edits + "/rms", [](nlohmann::json& j) {
    j["calibration"]["rms_px"] = 1e308;
  });
  ExpectRefused("fleet ingest --db " + db + " " + rms, "calibration.rms_px: recorded", db);
  // --recompute: a record whose checks cannot be recomputed (these generated ones hold no sphere spots) is refused.
  ExpectRefused("fleet ingest --recompute --db " + db + " " + rec, "cannot be recomputed", db);
  // A date that is not one (month 13).
  const std::string date = EditedRecord(rec, edits + "/date", [](nlohmann::json& j) {
    j["created_utc"] = "2026-13-01T08:00:00Z";
  });
  ExpectRefused("fleet ingest --db " + db + " " + date, "created_utc: '2026-13-01T08:00:00Z' is not an ISO 8601", db);
  // A station name with an invalid UTF-8 byte (was stored, after which every `fleet report --json` failed).
  ExpectRefused("fleet ingest --db " + db + " --station \"$(printf 'LINE-\\377')\" " + rec, "--station: must be non-empty UTF-8",
                db);
  // The same record re-indented and with its keys reordered is the same record (was a new row).
  const std::string same = EditedRecord(
      Dir("A") + "/SN-A-0003", edits + "/same", [](nlohmann::json&) {}, 7);
  ASSERT_NE(util::Sha256HexOfFile(same + "/unit.json"), util::Sha256HexOfFile(Dir("A") + "/SN-A-0003/unit.json"));
  const auto again = RunTopocal("fleet ingest --db " + db + " --station LINE-A " + same);
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find("0 record(s) added, 1 already present"), std::string::npos) << again.output;
  EXPECT_EQ(CountUnits(db), kUnitsPerStation);
}

TEST_F(FleetTest, ADamagedOrForeignDatabaseIsRefusedBeforeAnyWrite) {
  const std::string db = Db("ledger-damage");
  ASSERT_EQ(RunTopocal(Ingest(db, "A")).exit_code, 0);
  // `fleet check` passes a sound database; `fleet backup` copies it, and the copy reports the same line.
  const auto ok = RunTopocal("fleet check --db " + db);
  ASSERT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_NE(ok.output.find(fmt::format("ok: schema version 3, {} record(s)", kUnitsPerStation)), std::string::npos)
      << ok.output;
  const std::string copy = *work_ + "/ledger-backup.sqlite";
  ASSERT_EQ(RunTopocal("fleet backup --db " + db + " --out " + copy).exit_code, 0);
  ASSERT_EQ(RunTopocal("fleet check --db " + copy).exit_code, 0);
  EXPECT_EQ(FleetDb(copy, false).Units().size(), FleetDb(db, false).Units().size());
  ExpectRefused("fleet backup --db " + db + " --out " + db, "is also an input of this run", db);

  // A stored U of infinity, written by another program with SQLite's checks switched off: refused on reading
  // (was charted as inf).
  const std::string inf = Db("ledger-inf");
  fs::copy_file(copy, inf);
  ExecSql(inf, "PRAGMA ignore_check_constraints = ON; UPDATE measurements SET U = 9e999 WHERE rowid = 3");
  ExpectRefused("fleet report --db " + inf + " --out " + *work_ + "/inf.html", "corrupt: unit", inf);
  ExpectRefused("fleet check --db " + inf, "corrupt: unit", inf);
  EXPECT_FALSE(fs::exists(*work_ + "/inf.html"));

  // Damaged pages (a disk's bit rot, a copy cut short and patched): nothing ingested into it, nothing reported
  // from it (ingestion added the record and then exited 1).
  const std::string damaged = Db("ledger-damaged");
  fs::copy_file(copy, damaged);
  {
    std::fstream f(damaged, std::ios::in | std::ios::out | std::ios::binary);
    const std::size_t page = 4096;
    f.seekp(static_cast<std::streamoff>(2 * page + 8));  // inside the units table's first leaf page
    const std::string junk(600, '\xa5');
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  ExpectRefused(Ingest(damaged, "B"), "corrupt:", damaged);
  ExpectRefused("fleet check --db " + damaged, "restore it from a backup", damaged);
  ExpectRefused("fleet report --db " + damaged + " --out " + *work_ + "/damaged.html", "corrupt:", damaged);

  // Another layout under the fleet's identity and version: not a fleet database.
  const std::string foreign = Db("ledger-foreign");
  ExecSql(foreign, fmt::format("CREATE TABLE units(x); PRAGMA application_id = {}; PRAGMA user_version = {}",
                               kFleetApplicationId, kFleetSchemaVersion));
  ExpectRefused(Ingest(foreign, "A"), "tables or indexes differ from schema version 3", foreign);
}

TEST_F(FleetTest, ChromiumRendersTheFleetReport) {
  const std::string chromium = testing::FindChromium();
  ASSERT_FALSE(chromium.empty()) << "headless Chromium is required (Debian package `chromium`)";
  const std::string db = Db("browser");
  for (const char* s : {"A", "B", "C"}) ASSERT_EQ(RunTopocal(Ingest(db, s)).exit_code, 0);
  const std::string html = *work_ + "/browser.html", pdf = *work_ + "/browser.pdf";
  ASSERT_EQ(RunTopocal("fleet report --db " + db + " --out " + html).exit_code, 0);
  const std::string url = "file://" + fs::absolute(html).string();
  const auto printed = testing::Chromium(chromium, *work_, "fleet-pdf", "--no-pdf-header-footer --print-to-pdf=" + pdf + " " + url);
  ASSERT_EQ(printed.exit_code, 0) << printed.output;
  const auto dumped = testing::Chromium(chromium, *work_, "fleet-dom", "--dump-dom " + url);
  ASSERT_EQ(dumped.exit_code, 0) << dumped.output;
  const std::string& d = dumped.output;
  EXPECT_NE(d.find("data-units=\"60\""), std::string::npos);
  // Every parameter: a histogram and the line's chart; with three stations, three station charts each.
  std::size_t n_hist = 0, n_chart = 0;
  for (std::size_t p = d.find("<svg class=\"plot histogram\""); p != std::string::npos;
       p = d.find("<svg class=\"plot histogram\"", p + 1)) ++n_hist;
  for (std::size_t p = d.find("<svg class=\"plot chart\""); p != std::string::npos; p = d.find("<svg class=\"plot chart\"", p + 1)) {
    ++n_chart;
  }
  EXPECT_GE(n_hist, 4u);  // RMS, the sphere's radius and power, sigma, and the calibration's own parameters
  EXPECT_EQ(n_chart, 4 * n_hist);
  // The PDF: A4 pages with "Page n of N" on each.
  const auto text = testing::Shell("pdftotext -layout " + pdf + " - 2>&1");
  ASSERT_EQ(text.exit_code, 0) << text.output;
  const int pages = static_cast<int>(std::count(text.output.begin(), text.output.end(), '\f'));
  EXPECT_GE(pages, 3);
  EXPECT_NE(text.output.find(fmt::format("Page {} of {}", pages, pages)), std::string::npos);
  EXPECT_NE(text.output.find("Fleet report: the production line"), std::string::npos);
}

// The verdict of each unit against the limits, and the ones near them: built by hand, judged by AnalyseFleet.
TEST(FleetAnalysis, UnitsBeyondAndNearTheirLimitsAreListed) {
  const auto unit = [](const std::string& serial, double radius_error_mm, std::optional<double> U) {
    FleetUnit u;
    u.serial = serial;
    u.created_utc = "2026-10-01T08:00:00Z";
    u.station = "LINE-1";
    for (const char* key : {"calibration_rms_px", "sphere_power_error_D", "paper_rx_error_mm", "paper_ry_error_mm",
                            "paper_kx_error", "paper_ky_error"}) {
      u.measurements[key] = {key, 0.01, 0.001};
    }
    u.measurements["sphere_radius_error_mm"] = {"sphere_radius_error_mm", radius_error_mm, U};
    return u;
  };
  // Limit 0.05 mm, guarded: 0.02 + 0.01 = 0.03 passes clear; 0.032 + 0.01 = 0.042 >= 0.8 x 0.05 is near;
  // -0.045 + 0.01 = 0.055 fails; 0.02 without U cannot be judged by the guarded rule and fails.
  const FleetAnalysis a = AnalyseFleet("db", {unit("OK", 0.02, 0.01), unit("NEAR", 0.032, 0.01),
                                              unit("FAIL", -0.045, 0.01), unit("NOU", 0.02, std::nullopt)},
                                       DefaultLimits());
  ASSERT_EQ(a.verdicts.size(), 4u);
  EXPECT_TRUE(a.verdicts[0].pass);
  EXPECT_TRUE(a.verdicts[0].near.empty());
  EXPECT_TRUE(a.verdicts[1].pass);
  EXPECT_EQ(a.verdicts[1].near, std::vector<std::string>{"sphere_radius_error_mm"});
  EXPECT_FALSE(a.verdicts[2].pass);
  EXPECT_EQ(a.verdicts[2].failed, std::vector<std::string>{"sphere_radius_error_mm"});
  EXPECT_FALSE(a.verdicts[3].pass);
  // Simple acceptance judges |value| alone: the one without U passes, -0.045 passes but is near.
  Limits simple = DefaultLimits();
  simple.rule = DecisionRule::kSimple;
  const FleetAnalysis b = AnalyseFleet("db", a.units, simple);
  EXPECT_TRUE(b.verdicts[3].pass);
  EXPECT_TRUE(b.verdicts[2].pass);
  EXPECT_EQ(b.verdicts[2].near, std::vector<std::string>{"sphere_radius_error_mm"});
  // A unit without a sphere measurement is not verified.
  FleetUnit bare = unit("BARE", 0.0, 0.0);
  bare.measurements.erase("sphere_radius_error_mm");
  const FleetAnalysis c = AnalyseFleet("db", {bare}, DefaultLimits());
  EXPECT_FALSE(c.verdicts[0].pass);
  EXPECT_EQ(c.verdicts[0].failed.front(), "sphere_radius_error_mm (not measured)");
  const std::string html = RenderFleetHtml(a);
  EXPECT_NE(html.find("<tr data-serial=\"NEAR\">"), std::string::npos);
  EXPECT_NE(html.find("<tr data-serial=\"FAIL\">"), std::string::npos);
  EXPECT_EQ(html.find("<tr data-serial=\"OK\">"), std::string::npos);
}

}  // namespace
}  // namespace topocal::report

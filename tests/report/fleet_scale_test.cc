// The fleet at scale (docs/fleet.md "At scale"): a generated line of 2,000 units over four stations and three years
// (tests/report/fleet_fixture.h GenerateFleet: one station drifting over the last quarter, FAIL units), ingested
// through FleetDb::Ingest and reported by `topocal fleet report`: the counts, the FAIL units listed, the drift
// found on the drifting station's chart, every chart within kMaxChartPoints, the histograms SQLite bins equal to
// those of the values, and the report's queries on their indexes. The records are one real record (written by the
// record writer, read and verified) given each generated unit's serial, date and sphere radius error in memory:
// writing 2,000 record directories would take the test ~20 s (the calibration file's valid region is computed for
// each); bench/fleet_scale.sh ingests written records.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cstdlib>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "report/fleet_analysis.h"
#include "report/fleet_db.h"
#include "report/unit_record_reader.h"
#include "tests/cli_harness.h"
#include "tests/report/fleet_fixture.h"
#include "tests/report/record_fixture.h"
#include "util/io.h"
#include "util/sha256.h"

namespace topocal::report {
namespace {

using topocal::testing_cli::RunTopocal;

constexpr int kUnits = 2000;
// What the generated line gives with its seed (GenerateFleet, seed 5), checked against the generator's own counts.
constexpr unsigned kSeed = 5;

class FleetScaleTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    work_ = new std::string(testing::FreshDir("fleet-scale"));
    spec_ = new testing::FleetSpec;
    spec_->units = kUnits;
    spec_->seed = kSeed;
    fleet_ = new std::vector<testing::FleetLineUnit>(testing::GenerateFleet(*spec_));
    testing::WriteLineUnit(*work_ + "/template", testing::FixtureCalibration(), fleet_->front().unit);
    const UnitRecord base = ReadUnitRecord(*work_ + "/template");
    std::map<int, std::vector<UnitRecord>> by_station;
    for (const testing::FleetLineUnit& f : *fleet_) {
      UnitRecord r = base;
      r.serial = f.unit.serial;
      r.created_utc = f.unit.created_utc;
      r.unit_json_sha256 = r.unit_json_content_sha256 = util::Sha256Hex(f.unit.serial);
      r.directory = "generated/" + f.unit.serial;
      r.verification->corrected["radius_error_mm"] = f.unit.radius_error_mm;
      by_station[f.station].push_back(std::move(r));
    }
    FleetDb db(Db(), /*create=*/true);
    for (const auto& [station, records] : by_station) db.Ingest(records, testing::FleetStationName(station));
    const auto run = RunTopocal("fleet report --db " + Db() + " --out " + *work_ + "/fleet.html --json " + *work_ +
                                "/fleet.json --csv " + *work_ + "/fleet.csv");
    ASSERT_EQ(run.exit_code, 0) << run.output;
  }
  static void TearDownTestSuite() {
    // TOPOCAL_KEEP_FLEET=1 keeps the database and the reports (to look at them).
    const char* keep = std::getenv("TOPOCAL_KEEP_FLEET");
    if (!::testing::UnitTest::GetInstance()->Failed() && !(keep && *keep)) std::filesystem::remove_all(*work_);
    delete work_;
    delete spec_;
    delete fleet_;
  }
  static std::string Db() { return *work_ + "/fleet.sqlite"; }
  static nlohmann::json Json() { return nlohmann::json::parse(util::ReadFile(*work_ + "/fleet.json")); }
  static std::string* work_;
  static testing::FleetSpec* spec_;
  static std::vector<testing::FleetLineUnit>* fleet_;
};
std::string* FleetScaleTest::work_ = nullptr;
testing::FleetSpec* FleetScaleTest::spec_ = nullptr;
std::vector<testing::FleetLineUnit>* FleetScaleTest::fleet_ = nullptr;

TEST_F(FleetScaleTest, CountsAndEveryFailUnitAreReported) {
  const nlohmann::json j = Json();
  EXPECT_EQ(j.at("unit_count"), kUnits);
  EXPECT_FALSE(j.at("units_complete"));  // more than kMaxListedUnits: the listed units only
  std::map<std::string, std::pair<int, int>> expected;  // station: units, passed
  std::set<std::string> failing;
  for (const auto& f : *fleet_) {
    auto& e = expected[testing::FleetStationName(f.station)];
    ++e.first;
    e.second += f.fails ? 0 : 1;
    if (f.fails) failing.insert(f.unit.serial);
  }
  ASSERT_GE(failing.size(), 5u);  // the seed gives some (0.5 % of 2,000)
  for (const auto& y : j.at("yield")) {
    EXPECT_EQ(y.at("units"), expected.at(y.at("station")).first) << y.dump();
    EXPECT_EQ(y.at("passed"), expected.at(y.at("station")).second) << y.dump();
  }
  // Every FAIL unit, and only those, with its verdict in the JSON and a row on the page.
  std::set<std::string> listed;
  for (const auto& u : j.at("units")) {
    if (u.at("verdict") == "FAIL") listed.insert(u.at("serial").get<std::string>());
  }
  EXPECT_EQ(listed, failing);
  const std::string page = util::ReadFile(*work_ + "/fleet.html");
  for (const std::string& serial : failing) {
    EXPECT_NE(page.find("<tr data-serial=\"" + serial + "\"><td>" + serial), std::string::npos) << serial;
  }
  EXPECT_NE(page.find(fmt::format("data-units=\"{}\"", kUnits)), std::string::npos);
  EXPECT_NE(page.find("id=\"units-not-listed\""), std::string::npos);
  // The CSV has every unit: a header and one row per unit and stored parameter.
  const std::string csv = util::ReadFile(*work_ + "/fleet.csv");
  std::set<std::string> serials;
  for (std::size_t p = csv.find('\n') + 1; p < csv.size(); p = csv.find('\n', p) + 1) {
    serials.insert(csv.substr(p, csv.find(',', p) - p));
  }
  EXPECT_EQ(serials.size(), static_cast<std::size_t>(kUnits));
}

TEST_F(FleetScaleTest, TheDriftingStationIsFoundAndEveryChartIsBounded) {
  const nlohmann::json j = Json();
  const std::string drifting = testing::FleetStationName(spec_->drift_station);
  const std::string drift_from = fmt::format("SN-{:06d}", static_cast<int>(spec_->drift_from * kUnits) + 1);
  std::map<std::string, int> signals, late;
  for (const auto& c : j.at("charts")) {
    // No chart holds more than kMaxChartPoints points; a longer series is a chart of subgroup means of m units.
    EXPECT_LE(c.at("points").get<int>(), kMaxChartPoints) << c.dump();
    const int m = c.at("subgroup_size");
    EXPECT_EQ(c.at("points").get<int>(), (c.at("units").get<int>() + m - 1) / m) << c.dump();
    if (c.at("parameter") != "sphere_radius_error_mm") continue;
    const std::string station = c.at("station").is_null() ? "line" : c.at("station").get<std::string>();
    EXPECT_GT(m, 1) << station;  // 2,000 units on the line, ~500 on each station
    for (const auto& s : c.at("signals")) {
      ++signals[station];
      late[station] += s.at("last_serial").get<std::string>() >= drift_from ? 1 : 0;
    }
  }
  // The drift (to 2 sigma over the last quarter) flags the drifting station's late subgroups; a stable station
  // has the run rules' false alarms at most (measured 2, 2 and 1 signals with this seed).
  EXPECT_GE(late[drifting], 3) << drifting;
  EXPECT_GE(late[drifting], signals[drifting] / 2);
  for (int s = 0; s < spec_->stations; ++s) {
    if (s == spec_->drift_station) continue;
    EXPECT_LE(signals[testing::FleetStationName(s)], 4) << testing::FleetStationName(s);
  }
  // The page draws no chart with more points than the bound.
  const std::string page = util::ReadFile(*work_ + "/fleet.html");
  int charts = 0;
  for (std::size_t p = page.find("<svg class=\"plot chart\""); p != std::string::npos;
       p = page.find("<svg class=\"plot chart\"", p + 1)) {
    const std::size_t end = page.find("</svg>", p);
    int points = 0;
    for (std::size_t q = page.find("<circle class=\"point", p); q < end; q = page.find("<circle class=\"point", q + 1)) {
      ++points;
    }
    EXPECT_LE(points, kMaxChartPoints);
    ++charts;
  }
  EXPECT_GE(charts, 5 * 4);  // the line and four stations, for each of the charted parameters
}

TEST_F(FleetScaleTest, SqliteBinsTheHistogramsAsTheValuesAreBinnedAndTheQueriesUseIndexes) {
  const FleetDb db(Db(), /*create=*/false);
  std::map<std::string, std::vector<double>> values;
  db.ForEachUnit([&](FleetUnit&& u) {
    for (const auto& [key, m] : u.measurements) values[key].push_back(m.value);
  });
  for (const auto& [key, v] : values) {
    const plot::HistogramBins sql = db.Histogram(key), direct = plot::BinValues(v);
    EXPECT_EQ(sql.n, static_cast<std::int64_t>(v.size())) << key;
    EXPECT_EQ(sql.lo, direct.lo) << key;
    EXPECT_EQ(sql.hi, direct.hi) << key;
    EXPECT_EQ(sql.counts, direct.counts) << key;
  }
  EXPECT_LE(db.Histogram("sphere_radius_error_mm").counts.size(), static_cast<std::size_t>(plot::kMaxHistogramBins));
  // The plans: the units in time order from their index (no sort of 10^5 rows), the bins from the covering index.
  sqlite3* h = nullptr;
  ASSERT_EQ(sqlite3_open_v2(Db().c_str(), &h, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  const auto plan = [&](const std::string& sql) {
    sqlite3_stmt* st = nullptr;
    EXPECT_EQ(sqlite3_prepare_v2(h, ("EXPLAIN QUERY PLAN " + sql).c_str(), -1, &st, nullptr), SQLITE_OK);
    std::string text;
    while (sqlite3_step(st) == SQLITE_ROW) text += std::string(reinterpret_cast<const char*>(sqlite3_column_text(st, 3))) + "\n";
    sqlite3_finalize(st);
    return text;
  };
  const std::string units = plan(kFleetUnitsInTimeOrderSql), bins = plan(kFleetHistogramSql);
  sqlite3_close(h);
  EXPECT_NE(units.find("SCAN u USING INDEX units_by_time"), std::string::npos) << units;
  EXPECT_NE(units.find("SEARCH m USING INDEX sqlite_autoindex_measurements_1 (unit_id=?)"), std::string::npos) << units;
  EXPECT_EQ(units.find("TEMP B-TREE"), std::string::npos) << units;
  EXPECT_NE(bins.find("USING COVERING INDEX measurements_by_value (parameter=?)"), std::string::npos) << bins;
}

}  // namespace
}  // namespace topocal::report

// `topocal compare`: two measurements of one eye through the bundled device — the same eye twice (no change beyond
// the noise) and the eye after its flat meridian steepened — their numbers' changes with U and the change maps.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/cli_harness.h"
#include "util/io.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using topocal::testing_cli::RunTopocal;

class Compare : public topocal::testing_cli::TempDirTest {
 protected:
  // Renders `config` through the bundled device (spot noise seeded) and reconstructs it with its maps.
  void Measure(const std::string& name, const std::string& config, int seed, const std::string& extra = "") {
    const std::string device = std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json";
    ASSERT_EQ(RunTopocal("render-spots --config " + config + " --device " + device + " --seed " +
                         std::to_string(seed) + " --out " + Path(name + ".png"))
                  .exit_code,
              0);
    const auto r = RunTopocal("reconstruct --config " + paper_ + " --device " + device + " --image " +
                              Path(name + ".png") + " --json " + Path(name + ".json") + " --maps " +
                              Path(name + "-maps") + " " + extra);
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  json Quantity(const json& comparison, const std::string& key) {
    for (const auto& q : comparison["quantities"]) {
      if (q["key"] == key) return q;
    }
    ADD_FAILURE() << key << " not in the comparison";
    return json();
  }
  std::string Compared(const std::string& a, const std::string& b, const std::string& extra = "") {
    return "compare " + Path(a + ".json") + " " + Path(b + ".json") + " --a-maps " + Path(a + "-maps") +
           " --b-maps " + Path(b + "-maps") + " " + extra;
  }
};

TEST_F(Compare, TheSameEyeTwiceShowsNoClinicalChangeAndASteeperOneShowsItsChange) {
  Measure("visit1", paper_, 1, "--eye OD");
  Measure("visit2", paper_, 2, "--eye OD");
  // The flat meridian steepened: r_x 8.35 -> 8.25 mm, +0.49 D of keratometric power (337.5 / r).
  std::string config = topocal::util::ReadFile(paper_);
  const auto at = config.find("\"rx_mm\": 8.35");
  ASSERT_NE(at, std::string::npos);
  config.replace(at, std::string("\"rx_mm\": 8.35").size(), "\"rx_mm\": 8.25");
  std::ofstream(Path("steeper.json")) << config;
  Measure("visit3", Path("steeper.json"), 3, "--eye OD");

  auto r = RunTopocal(Compared("visit1", "visit2", "--maps " + Path("same") + " --json " + Path("same.json")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("eye OD"), std::string::npos) << r.output;
  const json same = json::parse(topocal::util::ReadFile(Path("same.json")));
  EXPECT_EQ(same["quantities"].size(), 15u);
  int compared = 0;
  for (const auto& q : same["quantities"]) {
    if (q["verdict"] == "not compared") continue;
    ++compared;
    EXPECT_GT(q["change_expanded"].get<double>(), 0.0) << q;
  }
  EXPECT_GE(compared, 13);  // every number with a determined U (peak locations may not be)
  // Noise only: far below the 0.25 D a clinician acts on (measured 2026-12-06: -0.0004 +- 0.0004 D).
  const json steep_same = Quantity(same, "clinical.sim_k.steep_D");
  EXPECT_LT(std::abs(steep_same["change"].get<double>()), 0.25);
  EXPECT_LT(std::abs(steep_same["change"].get<double>()), 0.005);
  for (const char* map : {"axial_power_change", "tangential_power_change", "elevation_change",
                          "axial_change_uncertainty"}) {
    EXPECT_TRUE(fs::exists(Path(std::string("same/") + map + ".png"))) << map;
    EXPECT_TRUE(fs::exists(Path(std::string("same/") + map + ".csv"))) << map;
  }

  r = RunTopocal(Compared("visit1", "visit3", "--json " + Path("steeper-change.json")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json steeper = json::parse(topocal::util::ReadFile(Path("steeper-change.json")));
  const json flat = Quantity(steeper, "clinical.sim_k.flat_D");
  // Expected +0.49 D (337.5 / 8.25 - 337.5 / 8.35); acceptance the clinical step 0.25 D around it, regression bound
  // near the value measured 2026-12-06 (+0.4848 +- 0.0003 D).
  EXPECT_NEAR(flat["change"].get<double>(), 0.49, 0.25);
  EXPECT_NEAR(flat["change"].get<double>(), 0.485, 0.01);
  EXPECT_EQ(flat["verdict"], "beyond U");
  // r_x recovered: -0.100000 +- 0.000026 mm measured (acceptance 0.01 mm, regression 0.001 mm).
  EXPECT_NEAR(Quantity(steeper, "surface_fit.rx_mm")["change"].get<double>(), -0.10, 0.01);
  EXPECT_NEAR(Quantity(steeper, "surface_fit.rx_mm")["change"].get<double>(), -0.10, 0.001);
  EXPECT_GT(steeper["axial_fraction_beyond_U"].get<double>(), 0.5);
  EXPECT_NE(r.output.find("BEYOND U: changed"), std::string::npos) << r.output;
}

TEST_F(Compare, WhatCannotBeComparedIsRefusedNamingTheFile) {
  Measure("right", paper_, 1, "--eye OD");
  Measure("left", paper_, 2, "--eye OS");
  auto r = RunTopocal(Compared("right", "left"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("not the same eye"), std::string::npos) << r.output;
  // A refused measurement has no numbers to compare.
  json refused = json::parse(topocal::util::ReadFile(Path("right.json")));
  refused["valid"] = false;
  topocal::util::WriteFileAtomic(Path("refused.json"), refused.dump());
  r = RunTopocal("compare " + Path("refused.json") + " " + Path("right.json"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("refused.json: valid is false"), std::string::npos) << r.output;
  // Maps asked for without their directories; a damaged map CSV: one line naming the file, nothing written.
  r = RunTopocal("compare " + Path("right.json") + " " + Path("right.json") + " --maps " + Path("out"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  std::ofstream(Path("left-maps/axial_power.csv"), std::ios::app) << "1,2,3,4\n";
  topocal::util::WriteFileAtomic(Path("left.json"), topocal::util::ReadFile(Path("right.json")));
  r = RunTopocal(Compared("right", "left", "--maps " + Path("out")));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("axial_power.csv: line"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("out")));
}

}  // namespace

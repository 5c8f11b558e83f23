// `topocal design --optimize`: the trade-off table, the chosen design's outputs, and a configuration every other
// verb takes; a goal nothing meets is refused in one line naming the goal file and key, with nothing written.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "tests/cli_harness.h"

namespace {

namespace fs = std::filesystem;

using topocal::testing_cli::RunTopocal;

class DesignOptimize : public topocal::testing_cli::TempDirTest {};

size_t Lines(const std::string& text) { return static_cast<size_t>(std::count(text.begin(), text.end(), '\n')); }

// One cornea and a 1 x 2 grid: a few seconds.
constexpr const char* kSmallGoal =
    R"({"corneas": ["kc-33um-0.85mm"], "rings": [14], "eta": [6, 8], "steepest_radius_mm": 6.5})";

TEST_F(DesignOptimize, TheWrittenConfigurationIsTakenByDesignAndSimulate) {
  Write("goal.json", kSmallGoal);
  const auto r = RunTopocal("design --config " + paper_ + " --optimize --goal " + Path("goal.json") + " --jobs 2" +
                            " --out " + Path("t.csv") + " --svg " + Path("s.svg") + " --config-out " +
                            Path("chosen.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // The table: the base design and both candidates, the choice and its reason.
  EXPECT_NE(r.output.find("| 12 rings x 8 (base) | 624 |"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("| 14 rings x 6 | 630 |"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("| 14 rings x 8 | 840 |"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("**chosen**"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Chosen: 14 rings x "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("configuration of the chosen design -> " + Path("chosen.json")), std::string::npos);

  // The configuration is accepted by design (the same targets) and simulate (one spot per target).
  const auto again = RunTopocal("design --config " + Path("chosen.json") + " --out " + Path("t2.csv"));
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_EQ(Bytes("t2.csv"), Bytes("t.csv"));
  const size_t targets = Lines(Bytes("t.csv")) - 1;
  EXPECT_TRUE(targets == 630 || targets == 840) << targets;
  const auto sim = RunTopocal("simulate --config " + Path("chosen.json") + " --sigma 0 --out " + Path("spots.csv"));
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  EXPECT_EQ(Lines(Bytes("spots.csv")) - 1, targets);
  EXPECT_NE(Bytes("s.svg").find(std::to_string(targets) + " spots"), std::string::npos);
}

TEST_F(DesignOptimize, AGoalNothingMeetsIsRefusedInOneLineWithNothingWritten) {
  Write("goal.json", R"({"corneas": ["kc-33um-0.85mm"], "rings": [12], "eta": [6], "pixel_pitch_um": 3.8,
                         "min_spot_radius_um": 8.0})");
  const auto r = RunTopocal("design --config " + paper_ + " --optimize --goal " + Path("goal.json") + " --out " +
                            Path("t.csv") + " --svg " + Path("s.svg") + " --config-out " + Path("chosen.json"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("topocal: " + Path("goal.json") + ": min_spot_radius_um: spots of "), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("No design chosen: "), std::string::npos) << r.output;  // the table says why too
  EXPECT_FALSE(fs::exists(Path("t.csv")));
  EXPECT_FALSE(fs::exists(Path("s.svg")));
  EXPECT_FALSE(fs::exists(Path("chosen.json")));

  // A bad goal key: refused before any search; --optimize without --config-out: refused.
  Write("bad.json", R"({"rings": [12], "eta": [6], "pixel_pitch": 1.4})");
  const auto bad = RunTopocal("design --config " + paper_ + " --optimize --goal " + Path("bad.json") + " --out " +
                              Path("t.csv") + " --config-out " + Path("chosen.json"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.output.find(Path("bad.json") + ": pixel_pitch: unknown key"), std::string::npos) << bad.output;
  const auto no_out = RunTopocal("design --config " + paper_ + " --optimize --out " + Path("t.csv"));
  EXPECT_EQ(no_out.exit_code, 2);
  EXPECT_NE(no_out.output.find("--optimize: needs --config-out"), std::string::npos) << no_out.output;
  EXPECT_FALSE(fs::exists(Path("t.csv")));
}

}  // namespace

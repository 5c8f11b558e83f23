// topocal harness end to end: the outputs, shards merged == single run byte for byte, and one-line refusals of bad
// input (exit 2) that leave no output behind.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "tests/cli_harness.h"

namespace {

namespace fs = std::filesystem;

using topocal::testing_cli::Run;
using topocal::testing_cli::RunTopocal;

const char* kOutputs[] = {"cases.csv", "summary.json", "table.md", "dk_vs_residual.svg", "dP_vs_residual.svg"};

class HarnessCli : public topocal::testing_cli::TempDirTest {
 protected:
  static std::string Read(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  // A small sweep: 2 sigmas x 3 calibration errors x 1 noise level = 6 cases (~0.1 s).
  std::string Config(const std::string& name, const std::string& replace_from = "", const std::string& replace_to = "") {
    std::string text = R"({"design": ")" + std::string(TOPOCAL_SOURCE_DIR) + R"(/data/paper.json", "seed": 3,
      "distortion": {"seidel_sigma_per_mm2": [-1e-6, 6.3e-5]},
      "noise_px": [0.01], "noise_draws": 1, "calibration_errors": [-1, 0, 0.1],
      "limits": {"dk": 0.05, "dP_D": 0.25}})";
    if (!replace_from.empty()) {
      const auto at = text.find(replace_from);
      EXPECT_NE(at, std::string::npos) << replace_from;
      if (at != std::string::npos) text.replace(at, replace_from.size(), replace_to);
    }
    std::ofstream(Path(name)) << text;
    return Path(name);
  }
};

TEST_F(HarnessCli, SingleRunWritesEveryOutputAndPrintsTheAnswer) {
  const auto r = RunTopocal("harness --config " + Config("h.json") + " --out " + Path("out"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("inverse answer: "), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("nan"), std::string::npos) << r.output;
  for (const char* name : kOutputs) {
    const std::string text = Read(Path("out/") + name);
    EXPECT_FALSE(text.empty()) << name;
    EXPECT_EQ(text.find("nan"), std::string::npos) << name;
  }
  const std::string csv = Read(Path("out/cases.csv"));
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + 6);
  EXPECT_NE(Read(Path("out/summary.json")).find("\"residual_max_um\""), std::string::npos);
}

TEST_F(HarnessCli, ThreeShardsMergeIntoTheSingleRunByteForByte) {
  const std::string config = Config("h.json");
  ASSERT_EQ(RunTopocal("harness --config " + config + " --out " + Path("single")).exit_code, 0);
  for (int i = 0; i < 3; ++i) {
    const auto r = RunTopocal("harness --config " + config + " --shard " + std::to_string(i) + "/3 --out " +
                              Path("s" + std::to_string(i)));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_TRUE(fs::exists(Path("s" + std::to_string(i) + "/shard-" + std::to_string(i) + "-of-3.json")));
  }
  // Shards given as directories and as a file, in any order.
  const auto m = RunTopocal("harness merge --out " + Path("merged") + " " + Path("s2") + " " + Path("s0") + " " +
                            Path("s1/shard-1-of-3.json"));
  ASSERT_EQ(m.exit_code, 0) << m.output;
  EXPECT_NE(m.output.find("inverse answer: "), std::string::npos);
  for (const char* name : kOutputs) {
    EXPECT_EQ(Read(Path("merged/") + name), Read(Path("single/") + name)) << name;
  }

  // Incomplete: shard 2 missing. A shard of another configuration. A shard given twice. Nothing is written.
  const auto missing = RunTopocal("harness merge --out " + Path("m1") + " " + Path("s0") + " " + Path("s1"));
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  EXPECT_NE(missing.output.find("shard 2/3 is missing"), std::string::npos) << missing.output;
  ASSERT_EQ(RunTopocal("harness --config " + Config("other.json", "\"seed\": 3", "\"seed\": 4") +
                       " --shard 2/3 --out " + Path("foreign"))
                .exit_code,
            0);
  const auto foreign = RunTopocal("harness merge --out " + Path("m2") + " " + Path("s0") + " " + Path("s1") + " " +
                                  Path("foreign"));
  EXPECT_EQ(foreign.exit_code, 2) << foreign.output;
  EXPECT_NE(foreign.output.find("config_sha256"), std::string::npos) << foreign.output;
  const auto twice = RunTopocal("harness merge --out " + Path("m3") + " " + Path("s0") + " " + Path("s1") + " " +
                                Path("s1") + " " + Path("s2"));
  EXPECT_EQ(twice.exit_code, 2) << twice.output;
  for (const auto* r : {&missing, &foreign, &twice}) {
    EXPECT_EQ(std::count(r->output.begin(), r->output.end(), '\n'), 1) << r->output;
  }
  for (const char* d : {"m1", "m2", "m3"}) EXPECT_FALSE(fs::exists(Path(d))) << d;
}

// Assembly errors through the command line: the per-axis answer printed and written, its plots, two shards merged
// into the single run's bytes, and a bad assembly value refused with one line.
TEST_F(HarnessCli, AssemblyAxesAnswerPerAxisAndShardLikeTheRest) {
  const std::string text = R"({"design": ")" + std::string(TOPOCAL_SOURCE_DIR) + R"(/data/paper.json", "seed": 3,
      "assembly": {"screen_axial_mm": [0, 0.5], "principal_point_offset_mm": [0.01], "azimuths_deg": [0, 90]},
      "noise_px": [0], "limits": {"dk": 0.05, "dP_D": 0.25, "dP_maps": "axial"}})";
  std::ofstream(Path("a.json")) << text;
  const auto r = RunTopocal("harness --config " + Path("a.json") + " --out " + Path("single"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("assembly answer: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("  screen_axial_mm: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("  principal_point_offset_mm: "), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("inverse answer: "), std::string::npos) << r.output;  // no distortion swept
  const char* outputs[] = {"cases.csv", "summary.json", "table.md", "assembly_screen_axial_mm.svg",
                           "assembly_principal_point_offset_mm.svg"};
  for (const char* name : outputs) EXPECT_FALSE(Read(Path("single/") + name).empty()) << name;
  EXPECT_FALSE(fs::exists(Path("single/dk_vs_residual.svg")));
  const std::string csv = Read(Path("single/cases.csv"));
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + 2 + 2);
  EXPECT_NE(Read(Path("single/summary.json")).find("\"assembly_answer\""), std::string::npos);
  for (int i = 0; i < 2; ++i) {
    const auto s = RunTopocal("harness --config " + Path("a.json") + " --shard " + std::to_string(i) + "/2 --out " +
                              Path("s" + std::to_string(i)));
    ASSERT_EQ(s.exit_code, 0) << s.output;
  }
  ASSERT_EQ(RunTopocal("harness merge --out " + Path("merged") + " " + Path("s1") + " " + Path("s0")).exit_code, 0);
  for (const char* name : outputs) EXPECT_EQ(Read(Path("merged/") + name), Read(Path("single/") + name)) << name;

  std::string bad = text;
  bad.replace(bad.find("[0.01]"), 6, "[-0.01]");
  std::ofstream(Path("bad.json")) << bad;
  const auto refused = RunTopocal("harness --config " + Path("bad.json") + " --out " + Path("bad_out"));
  EXPECT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_NE(refused.output.find("bad.json: assembly.principal_point_offset_mm[0]: must be >= 0 mm"), std::string::npos)
      << refused.output;
  EXPECT_EQ(std::count(refused.output.begin(), refused.output.end(), '\n'), 1) << refused.output;
  EXPECT_FALSE(fs::exists(Path("bad_out")));
}

TEST_F(HarnessCli, RefusesBadInputWithOneLineAndNoOutput) {
  const struct {
    std::string from, to, expect;
  } configs[] = {
      {"\"noise_px\": [0.01]", "\"noise_px\": []", "noise_px: must not be empty"},
      {"\"noise_px\": [0.01]", "\"noise_px\": [-0.01]", "noise_px[0]: must be >= 0"},
      {"[-1e-6, 6.3e-5]", R"({"from": 1e-4, "to": 1e-5, "count": 3, "spacing": "log"})", ".from: must not exceed to"},
      {"[-1e-6, 6.3e-5]", R"({"from": 1e-5, "to": 1e-4, "count": 0})", ".count: must be >= 1"},
      {"\"seed\": 3", "\"seed\": 3, \"colour\": 1", "colour: unknown key"},
  };
  int n = 0;
  for (const auto& c : configs) {
    const std::string out = Path("out" + std::to_string(n));
    const auto r = RunTopocal("harness --config " + Config("bad" + std::to_string(n++) + ".json", c.from, c.to) +
                              " --out " + out);
    EXPECT_EQ(r.exit_code, 2) << c.to << ": " << r.output;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(".json: "), std::string::npos) << r.output;  // names the file
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(out)) << c.to;
  }
  const std::string good = Config("good.json");
  // Each launch costs ~0.1-0.4 s of process start; tests/harness/harness_test.cc parses every other malformed form.
  for (const char* shard : {"3/3", "0/0", "x/3"}) {
    const auto r = RunTopocal("harness --config " + good + " --shard " + shard + " --out " + Path("shard_out"));
    EXPECT_EQ(r.exit_code, 2) << shard << ": " << r.output;
    EXPECT_NE(r.output.find("--shard"), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(Path("shard_out"))) << shard;
  }
  const auto no_config = RunTopocal("harness --out " + Path("x"));
  EXPECT_EQ(no_config.exit_code, 2) << no_config.output;
  const auto no_shards = RunTopocal("harness merge --out " + Path("y") + " " + Path("nowhere"));
  EXPECT_EQ(no_shards.exit_code, 2) << no_shards.output;
  EXPECT_FALSE(fs::exists(Path("y")));
}

}  // namespace

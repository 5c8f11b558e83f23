// The command line end to end: outputs, exit codes and one-line messages for bad input, no partial files.
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "tests/cli_harness.h"

namespace {

namespace fs = std::filesystem;

using topocal::testing_cli::Run;
using topocal::testing_cli::RunTopocal;

class Cli : public topocal::testing_cli::TempDirTest {};

TEST_F(Cli, DesignWritesTargetPoints) {
  const auto r = RunTopocal("design --config " + paper_ + " --out " + Path("t.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(Path("t.csv"));
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "ring,index,x_mm,y_mm,z_mm");
  int lines = 0;
  for (std::string l; std::getline(in, l);) ++lines;
  EXPECT_EQ(lines, 624);
}

TEST_F(Cli, SimulateWritesSpots) {
  const auto r = RunTopocal("simulate --config " + paper_ + " --sigma 2e-4 --out " + Path("s.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(Path("s.csv"));
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "ring,index,x_mm,y_mm");
}

TEST_F(Cli, SweepPrintsTableVAndWritesJson) {
  const auto r = RunTopocal("sweep --config " + paper_ + " --json " + Path("sweep.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* table : {"Table V ", "Table VI ", "Table VII "}) EXPECT_NE(r.output.find(table), std::string::npos);
  EXPECT_TRUE(fs::exists(Path("sweep.json")));
  EXPECT_EQ(r.output.find("nan"), std::string::npos);
}

TEST_F(Cli, SweepCorrectPrintsBeforeAndAfterAndWritesTheCorrectedRows) {
  // Two sigmas keep the closed loop short; the pipeline test covers all of Table IV.
  std::ifstream in(paper_);
  std::string cfg((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string list = "[-2.0e-4, -6.3e-5, -1.41e-6, 0.0, 1.41e-6, 6.3e-5, 2.0e-4]";
  ASSERT_NE(cfg.find(list), std::string::npos);
  cfg.replace(cfg.find(list), list.size(), "[0.0, 2.0e-4]");
  Write("two.json", cfg);
  const auto r = RunTopocal("sweep --config " + Path("two.json") + " --correct --json " + Path("s.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Before / after correction"), std::string::npos);
  std::ifstream js(Path("s.json"));
  const std::string json((std::istreambuf_iterator<char>(js)), std::istreambuf_iterator<char>());
  for (const char* key : {"\"corrected\"", "\"calibration\"", "\"sigma_estimated_per_mm2\"", "\"residual_rms_px\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
  // A camera file that does not exist is bad input, and nothing is written.
  const auto bad = RunTopocal("sweep --config " + Path("two.json") + " --correct --camera " + Path("none.json") +
                              " --json " + Path("t.json"));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_EQ(bad.output.find("Table V"), std::string::npos) << "bad input must fail before any work";
  EXPECT_FALSE(fs::exists(Path("t.json")));
}

TEST_F(Cli, ReconstructFromSimulatedSpotsWritesJsonAndMaps) {
  ASSERT_EQ(RunTopocal("simulate --config " + paper_ + " --sigma 0 --out " + Path("s.csv")).exit_code, 0);
  const auto r = RunTopocal("reconstruct --config " + paper_ + " --spots " + Path("s.csv") + " --truth --json " +
                            Path("r.json") + " --maps " + Path("maps"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("rx = 8.3500"), std::string::npos) << r.output;
  std::ifstream in(Path("r.json"));
  const std::string json((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const char* key : {"\"surface_fit\"", "\"stddev\"", "\"errors\"", "\"coefficients\"", "\"pv_um\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
  for (const char* f : {"axial_power.png", "tangential_power.csv", "elevation.png", "elevation.csv", "height_difference.png"}) {
    EXPECT_TRUE(fs::exists(Path("maps/") + f)) << f;
  }
}

TEST_F(Cli, ReconstructFromARawImageDetectsIndexesAndReconstructs) {
  const std::string camera = std::string(TOPOCAL_SOURCE_DIR) + "/data/camera.json";
  ASSERT_EQ(RunTopocal("render-spots --config " + paper_ + " --camera " + camera + " --sigma 0 --out " +
                       Path("spots.png")).exit_code, 0);
  const auto r = RunTopocal("reconstruct --config " + paper_ + " --image " + Path("spots.png") + " --camera " +
                            camera + " --truth --json " + Path("r.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("624 spots indexed"), std::string::npos) << r.output;
  // Centroids within ~0.02 px (issue 6) keep the undistorted camera's cornea within 0.001 mm / 0.005 in k.
  EXPECT_NE(r.output.find("rx = 8.350"), std::string::npos) << r.output;
  // --uncertainty needs a calibration to draw from.
  const auto no_cal = RunTopocal("reconstruct --config " + paper_ + " --image " + Path("spots.png") + " --camera " +
                                 camera + " --uncertainty 10");
  EXPECT_EQ(no_cal.exit_code, 2);
  EXPECT_NE(no_cal.output.find("--uncertainty needs --image and --calibration"), std::string::npos) << no_cal.output;
  // --image needs a camera; --camera does not go with --spots.
  EXPECT_EQ(RunTopocal("reconstruct --config " + paper_ + " --image " + Path("spots.png")).exit_code, 2);
  Write("s.csv", "ring,index,x_mm,y_mm\n");
  const auto mixed = RunTopocal("reconstruct --config " + paper_ + " --spots " + Path("s.csv") + " --camera " + camera);
  EXPECT_EQ(mixed.exit_code, 2);
  EXPECT_NE(mixed.output.find("--camera, --device and --calibration go with --image"), std::string::npos) << mixed.output;
}

TEST_F(Cli, ReconstructRejectsBadSpotsFiles) {
  Write("bad.csv", "ring,index,x_mm,y_mm\n1,0,0.1,abc\n");
  auto r = RunTopocal("reconstruct --config " + paper_ + " --spots " + Path("bad.csv") + " --json " + Path("r.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.output, "topocal: " + Path("bad.csv") + ":2: expected 'ring,index,x_mm,y_mm' numbers\n");
  EXPECT_FALSE(fs::exists(Path("r.json")));
  Write("few.csv", "ring,index,x_mm,y_mm\n1,0,0.031,0\n1,1,0.02,0.02\n");
  r = RunTopocal("reconstruct --config " + paper_ + " --spots " + Path("few.csv") + " --json " + Path("r.json"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("reconstruction failed: 2 spots"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("r.json")));
}

TEST_F(Cli, BadConfigIsOneLineAndExitTwoWithNoOutput) {
  Write("bad.json", R"({"ideal_image": {}})");
  const auto r = RunTopocal("simulate --config " + Path("bad.json") + " --sigma 0 --out " + Path("s.csv"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.output, "topocal: " + Path("bad.json") + ": ideal_image.rho0_mm: missing\n");
  EXPECT_FALSE(fs::exists(Path("s.csv")));
}

TEST_F(Cli, MissingConfigFile) {
  const auto r = RunTopocal("sweep --config " + Path("nope.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.output, "topocal: " + Path("nope.json") + ": (file): cannot be opened for reading\n");
}

TEST_F(Cli, UnwritableOutputLeavesNothing) {
  const auto r = RunTopocal("design --config " + paper_ + " --out " + Path("no/such/dir/t.csv"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("no/such/dir/t.csv: cannot be written"), std::string::npos) << r.output;
}

TEST_F(Cli, UsageErrorsExitTwoAndHelpExitsZero) {
  EXPECT_EQ(RunTopocal("sweep").exit_code, 2);
  EXPECT_EQ(RunTopocal("frobnicate").exit_code, 2);
  for (const char* verb : {"design", "simulate", "sweep", "reconstruct"}) {
    const auto r = RunTopocal(std::string(verb) + " --help");
    EXPECT_EQ(r.exit_code, 0) << verb;
    EXPECT_NE(r.output.find("--config"), std::string::npos) << verb;
  }
}

}  // namespace

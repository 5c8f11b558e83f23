// The maps of an analysis set are computed and written on several threads (MapSetOptions::jobs, issue 15): the
// files must not depend on the thread count.
#include "pipeline/map_output.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "model/config.h"
#include "topo/analysis.h"
#include "topo/sweep.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

namespace fs = std::filesystem;

TEST(MapOutput, TheFilesAreTheSameWhateverTheThreadCount) {
  const model::Config config = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  std::vector<topo::Analysis> analyses;
  for (const double sigma : {0.0, 6.3e-5}) {
    std::vector<topo::MeasuredSpot> spots;
    for (const auto& s : topo::SimulateSpots(config, sigma).spots) spots.push_back({s.id, s.position_mm});
    analyses.push_back(topo::AnalyzeSpots(spots, design.targets, config, nullptr));
  }
  const fs::path root = fs::temp_directory_path() / ("topocal-map-output-" + std::to_string(::getpid()));
  fs::remove_all(root);
  std::vector<fs::path> dirs;
  for (const int jobs : {1, 3}) {
    MapSetOptions o;
    o.size_px = 200;  // small pictures: the test is about the files being equal
    o.jobs = jobs;
    dirs.push_back(root / std::to_string(jobs));
    WriteAnalysisMapSet(dirs.back().string(),
                        {{"a_", " - a", &analyses[0], &config.cornea, {}}, {"b_", " - b", &analyses[1], &config.cornea, {}}},
                        o);
  }
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dirs[0])) {
    const fs::path other = dirs[1] / entry.path().filename();
    ASSERT_TRUE(fs::exists(other)) << other;
    EXPECT_EQ(util::ReadFile(entry.path().string()), util::ReadFile(other.string())) << entry.path().filename();
    ++files;
  }
  // 2 entries x 4 kinds (axial, tangential, elevation, height difference) x CSV and PNG.
  EXPECT_EQ(files, 16);
  EXPECT_EQ(std::distance(fs::directory_iterator(dirs[1]), fs::directory_iterator{}), files);
  fs::remove_all(root);
}

}  // namespace
}  // namespace topocal::pipeline

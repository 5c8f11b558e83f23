// The maps of an analysis set: the files do not depend on the thread count (MapSetOptions::jobs), the sim-K axes
// are drawn only where there is a cylinder, and the overview page carries the maps and the clinical numbers.
#include "pipeline/map_output.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
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
    std::vector<model::PlaneSpot> spots;
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

// Dark pixels (all channels below 60: black lines, not the scale's colours) in the annulus 2.2-3.8 mm of a power
// map, away from the sim-K rings (0.5, 1.5 mm), the supported circle and the labels: only the sim-K axes draw there.
int AxisPixels(const std::string& png) {
  const cv::Mat img = cv::imread(png);
  // The plot's square: the bounding box of the no-data grey, which fills its corners outside the data's disc.
  // Runs of at least 20 grey pixels (anti-aliased text has single ones).
  int x0 = img.cols, x1 = -1, y0 = img.rows, y1 = -1;
  for (int y = 0; y < img.rows; ++y) {
    int run = 0;
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b p = img.at<cv::Vec3b>(y, x);
      run = (p[0] == 205 && p[1] == 205 && p[2] == 205) ? run + 1 : 0;
      if (run >= 20) x0 = std::min(x0, x - 19), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
  }
  const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1), half = 0.5 * (x1 - x0);
  int dark = 0;
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const double r = std::hypot(x - cx, y - cy) / half;  // 1 = the plot's half width
      const cv::Vec3b p = img.at<cv::Vec3b>(y, x);
      if (r > 0.42 && r < 0.72 && p[0] < 60 && p[1] < 60 && p[2] < 60) ++dark;
    }
  }
  return dark;
}

// The sim-K axes are drawn where the cornea has a cylinder to show, and not on a sphere (0.00 D: its axes would be
// noise drawn as fact).
TEST(MapOutput, SimKAxesOnlyWhereThereIsACylinder) {
  model::Config config = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  const fs::path root = fs::temp_directory_path() / ("topocal-map-axes-" + std::to_string(::getpid()));
  fs::remove_all(root);
  std::vector<int> dark;
  for (const bool sphere : {false, true}) {
    if (sphere) config.cornea = {7.8, 7.8, 0.0, 0.0, 0.0};
    const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
    std::vector<model::PlaneSpot> spots;
    for (const auto& s : topo::SimulateSpots(config, 0.0).spots) spots.push_back({s.id, s.position_mm});
    const topo::Analysis a = topo::AnalyzeSpots(spots, design.targets, config, nullptr);
    ASSERT_TRUE(a.clinical_ok);
    EXPECT_EQ(a.clinical.CylinderD() < 0.005, sphere) << a.clinical.CylinderD();
    MapSetOptions o;
    o.size_px = 400;
    const fs::path dir = root / (sphere ? "sphere" : "paper");
    WriteAnalysisMapSet(dir.string(), {{"", "", &a, nullptr, {}}}, o);
    dark.push_back(AxisPixels((dir / "axial_power.png").string()));
  }
  // The paper cornea (3.8 D of cylinder): two axes cross the annulus, each 4 x 1.6 mm of line 2-4 px wide at about
  // 37 px/mm (and its contour lines); the sphere: not one dark pixel.
  EXPECT_GT(dark[0], 100);
  EXPECT_EQ(dark[1], 0);
  fs::remove_all(root);
}

// The overview page: written only when asked for, beside the maps; its text is the analysis's clinical numbers as
// the JSON has them, then the caller's lines (the capture's quality).
TEST(MapOutput, TheOverviewPageCarriesTheMapsAndTheClinicalNumbers) {
  const model::Config config = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  std::vector<model::PlaneSpot> spots;
  for (const auto& s : topo::SimulateSpots(config, 0.0).spots) spots.push_back({s.id, s.position_mm});
  const topo::Analysis a = topo::AnalyzeSpots(spots, design.targets, config, nullptr);
  ASSERT_TRUE(a.clinical_ok);
  const std::vector<std::string> lines = ClinicalSummaryLines(a);
  ASSERT_EQ(lines.size(), 4u);
  const auto& c = a.clinical;
  EXPECT_EQ(lines[0].rfind(fmt::format("sim-K {:.2f} D @ {:.0f}", c.steep_k_D, c.steep_axis_deg), 0), 0u) << lines[0];
  EXPECT_EQ(lines[1], fmt::format("Kmax {:.2f} D at ({:+.2f}, {:+.2f}) mm", c.kmax_D, c.kmax_at_mm.x(), c.kmax_at_mm.y()));
  EXPECT_EQ(lines[2].rfind(fmt::format("elevation peak {:.2f} \u00b5m at (", c.elevation_peak_um), 0), 0u) << lines[2];
  EXPECT_EQ(lines[3].rfind(fmt::format("best-fit sphere R = {:.3f} mm", c.bfs_radius_mm), 0), 0u) << lines[3];
  EXPECT_NE(ClinicalSummaryLines(a, false, false)[1].find("not determined"), std::string::npos);

  const fs::path root = fs::temp_directory_path() / ("topocal-map-overview-" + std::to_string(::getpid()));
  fs::remove_all(root);
  MapSetOptions o;
  o.size_px = 400;
  WriteAnalysisMapSet((root / "plain").string(), {{"", "", &a, nullptr, {}}}, o);
  EXPECT_FALSE(fs::exists(root / "plain" / "overview.png"));
  o.overview = true;
  o.eye = "OD";
  o.overview_lines = {"capture: 624 of 624 spots identified"};
  WriteAnalysisMapSet((root / "page").string(), {{"", "", &a, nullptr, {}}}, o);
  const cv::Mat page = cv::imread((root / "page" / "overview.png").string());
  ASSERT_FALSE(page.empty());
  // Two rows of two cells (axial, tangential; elevation, the numbers): taller than wide, as a portrait page.
  EXPECT_GT(page.rows, page.cols);
  const cv::Mat axial = cv::imread((root / "page" / "axial_power.png").string());
  EXPECT_LT(page.cols, 2 * axial.cols);  // the maps at half size
  fs::remove_all(root);
}

}  // namespace
}  // namespace topocal::pipeline

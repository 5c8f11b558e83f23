// Map scales on a real sweep: `topocal sweep --maps` on the paper's configuration writes every sigma's
// maps; the power maps of the whole sweep are on one scale (the standard absolute one), and SelectMapScale, run on
// the sweep's own grids (read back from the CSVs beside the PNGs), gives shared, absolute and minimum-span scales that
// hold every map.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "plot/map_image.h"
#include "tests/cli_harness.h"
#include "tests/report/record_fixture.h"
#include "util/io.h"

namespace topocal::report {
namespace {

namespace fs = std::filesystem;
using topocal::testing_cli::RunTopocal;

// A CSV written by plot::WriteMapCsv (square grid, y then x ascending, empty = no data) back as a GridMap.
model::GridMap ReadGridCsv(const std::string& path, const std::string& unit) {
  std::istringstream in(util::ReadFile(path));
  std::string line;
  std::getline(in, line);
  std::vector<double> xs, ys, values;
  while (std::getline(in, line)) {
    const std::size_t a = line.find(','), b = line.find(',', a + 1);
    xs.push_back(std::stod(line.substr(0, a)));
    ys.push_back(std::stod(line.substr(a + 1, b - a - 1)));
    const std::string v = line.substr(b + 1);
    values.push_back(v.empty() ? std::nan("") : std::stod(v));
  }
  model::GridMap g;
  g.nx = g.ny = static_cast<int>(std::lround(std::sqrt(static_cast<double>(values.size()))));
  g.x_min_mm = xs.front();
  g.x_max_mm = xs.back();
  g.y_min_mm = ys.front();
  g.y_max_mm = ys.back();
  g.values = values;
  g.unit = unit;
  return g;
}

TEST(SweepMaps, EveryPowerMapOfASweepSharesOneScale) {
  const std::string dir = testing::FreshDir("sweep");
  const auto run = RunTopocal("sweep --config " + std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json --maps " + dir);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  std::vector<std::string> sigmas;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.size() > 16 && name.substr(name.size() - 16) == "_axial_power.png") sigmas.push_back(name.substr(0, name.size() - 16));
  }
  std::sort(sigmas.begin(), sigmas.end());
  ASSERT_GE(sigmas.size(), 5u);  // the paper's sigmas
  std::vector<model::GridMap> axial, elevation;
  for (const std::string& s : sigmas) {
    axial.push_back(ReadGridCsv(dir + "/" + s + "_axial_power.csv", "D"));
    elevation.push_back(ReadGridCsv(dir + "/" + s + "_elevation.csv", "\u00b5m"));
  }
  std::vector<const model::GridMap*> axial_set, elevation_set;
  for (const auto& g : axial) axial_set.push_back(&g);
  for (const auto& g : elevation) elevation_set.push_back(&g);

  // Standard absolute scale: the same for the whole sweep and for each map alone (data-independent); widened to the
  // data it holds every map of the set.
  const plot::MapScale all = plot::SelectMapScale(axial_set, plot::StandardPowerScale());
  double lo = 1e9, hi = -1e9;
  for (const auto* g : axial_set) {
    const plot::MapScale one = plot::SelectMapScale({g}, plot::StandardPowerScale());
    EXPECT_EQ(one.value_min, all.value_min);
    EXPECT_EQ(one.value_max, all.value_max);
    for (double v : g->values) {
      if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    }
  }
  EXPECT_DOUBLE_EQ(all.contour_step, plot::kStandardPowerStepD);
  plot::MapScaleRequest widen = plot::StandardPowerScale();
  widen.widen_to_data = true;
  const plot::MapScale held = plot::SelectMapScale(axial_set, widen);
  EXPECT_LE(held.value_min, lo);
  EXPECT_GE(held.value_max, hi);
  EXPECT_NEAR(std::remainder(held.value_min - plot::kStandardPowerLowD, plot::kStandardPowerStepD), 0.0, 1e-9);
  // Shared normalised scale of the sweep's elevations: holds every map, wider than any one alone needs.
  const plot::MapScale shared = plot::SelectMapScale(elevation_set, plot::NormalisedScale(plot::kMinNormalisedSpanUm));
  for (const auto* g : elevation_set) {
    const plot::MapScale one = plot::SelectMapScale({g}, plot::NormalisedScale(plot::kMinNormalisedSpanUm));
    EXPECT_LE(shared.value_min, one.value_min);
    EXPECT_GE(shared.value_max, one.value_max);
    EXPECT_GE(one.value_max - one.value_min, plot::kMinNormalisedSpanUm);
  }

  // The PNGs as written: every axial map has the same width and the same colour bar and tick labels (the right
  // fifth of the image, rows below the title and above the footer, which grows by a line on a map that goes beyond
  // the scale), i.e. one scale across the sweep.
  const cv::Mat first = cv::imread(dir + "/" + sigmas.front() + "_axial_power.png");
  ASSERT_FALSE(first.empty());
  const cv::Rect bar_side(first.cols * 82 / 100, first.rows / 4, first.cols - first.cols * 82 / 100, first.rows / 2);
  int beyond = 0;
  for (const std::string& s : sigmas) {
    const cv::Mat img = cv::imread(dir + "/" + s + "_axial_power.png");
    ASSERT_EQ(img.cols, first.cols) << s;
    ASSERT_GE(img.rows, bar_side.y + bar_side.height) << s;
    EXPECT_EQ(cv::norm(img(bar_side), first(bar_side), cv::NORM_INF), 0.0) << s << ": another colour bar";
    beyond += img.rows != first.rows ? 1 : 0;
  }
  // The paper's strongest distortions push the periphery beyond 35.5-50.5 D: those maps say so in a footer line.
  EXPECT_GT(beyond, 0);
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace topocal::report

#include <gtest/gtest.h>

#include "model/config.h"
#include "topo/sweep.h"

namespace topocal::topo {
namespace {

// Acceptance: beta_e = 17.000 deg +- 0.001 deg for every sigma (Seidel distortion is radial and cannot rotate the
// contour); E_A within 1 percentage point of the paper's Table V.
constexpr double kBetaToleranceDeg = 0.001;
constexpr double kAreaChangeTolerancePct = 1.0;

TEST(TableV, ContourOrientationAndAreaChangeMatchThePaper) {
  const auto config = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  const auto result = RunSweep(config);
  ASSERT_EQ(result.spots, 624);
  // Paper Table V, E_A (%) by sigma; sigma = 0 is the reference (0 %).
  const std::vector<std::pair<double, double>> paper = {{-2.0e-4, 20.89}, {-6.3e-5, 6.36}, {-1.41e-6, 0.14},
                                                        {0.0, 0.0},       {1.41e-6, -0.14}, {6.3e-5, -6.16},
                                                        {2.0e-4, -18.90}};
  ASSERT_EQ(result.rows.size(), paper.size());
  for (size_t i = 0; i < paper.size(); ++i) {
    const auto& row = result.rows[i];
    EXPECT_DOUBLE_EQ(row.sigma_per_mm2, paper[i].first);
    EXPECT_EQ(row.spots_imaged, 624);
    EXPECT_NEAR(row.image_ellipse.beta_deg, 17.0, kBetaToleranceDeg) << "sigma " << row.sigma_per_mm2;
    EXPECT_NEAR(row.area_change_pct, paper[i].second, kAreaChangeTolerancePct) << "sigma " << row.sigma_per_mm2;
  }
  // Pincushion (sigma < 0) enlarges, barrel shrinks, monotonically.
  for (size_t i = 1; i < result.rows.size(); ++i) {
    EXPECT_LT(result.rows[i].image_ellipse.AreaMm2(), result.rows[i - 1].image_ellipse.AreaMm2());
  }
}

}  // namespace
}  // namespace topocal::topo

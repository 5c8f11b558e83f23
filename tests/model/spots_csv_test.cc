// The spots file (model/spots_csv.h) round trip on real output: the paper's design imaged through the paper's
// cornea (what `topocal simulate` writes), written and read back; every spot comes back with its id and the exact
// double (fmt's shortest representation round-trips).
#include "model/spots_csv.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "model/config.h"
#include "model/null_screen.h"
#include "model/surface.h"
#include "util/io.h"

namespace topocal::model {
namespace {

TEST(SpotsCsv, ASimulatedImageIsReadBackExactly) {
  const Config cfg = LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  const auto design = DesignNullScreen(cfg.ideal_image, cfg.topographer);
  const auto image = SynthesizeImage(Biconic{cfg.cornea}, Topographer{cfg.topographer}, design.targets);
  ASSERT_GT(image.spots.size(), 100u);
  const auto path =
      (std::filesystem::temp_directory_path() / fmt::format("topocal_spots_csv_{}.csv", ::getpid())).string();
  util::WriteFileAtomic(path, SpotsCsv(image.spots));
  const auto rows = ReadSpotsCsv(path);
  std::filesystem::remove(path);
  ASSERT_EQ(rows.size(), image.spots.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].id, image.spots[i].id) << i;
    EXPECT_EQ(rows[i].x_mm, image.spots[i].position_mm.x()) << i;
    EXPECT_EQ(rows[i].y_mm, image.spots[i].position_mm.y()) << i;
  }
}

}  // namespace
}  // namespace topocal::model

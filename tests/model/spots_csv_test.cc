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
    EXPECT_EQ(rows[i].position_mm.x(), image.spots[i].position_mm.x()) << i;
    EXPECT_EQ(rows[i].position_mm.y(), image.spots[i].position_mm.y()) << i;
  }
}

// Rows a reader must refuse, naming the file and line: a number beyond a double's range (read as 1.797e308 before),
// a missing field, text where a number goes, a value after the last column.
TEST(SpotsCsv, MalformedRowsAreRefusedNamingTheLine) {
  const auto path =
      (std::filesystem::temp_directory_path() / fmt::format("topocal_spots_bad_{}.csv", ::getpid())).string();
  for (const char* row : {"1,0,0.1,1e309", "1,0,-1e400,0.2", "1,0,0.1", "1,0,abc,0.2", "1,0,0.1,0.2,7"}) {
    util::WriteFileAtomic(path, std::string("ring,index,x_mm,y_mm\n1,1,0.1,0.2\n") + row + "\n");
    try {
      ReadSpotsCsv(path);
      ADD_FAILURE() << row << " was accepted";
    } catch (const util::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(path + ":3:"), std::string::npos) << row << ": " << e.what();
    }
  }
  util::WriteFileAtomic(path, "ring,index,x_mm,y_mm\n1,1,0.1,1e300\n");  // large but a double: read
  EXPECT_EQ(ReadSpotsCsv(path).at(0).position_mm.y(), 1e300);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace topocal::model

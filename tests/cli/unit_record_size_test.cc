// The size of what the line keeps and prints: a unit record holds its maps as PNGs (the CSV grids behind them only
// with --map-csv) and its QA report embeds them, within the budgets a line's storage and a mail attachment allow.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>

#include "tests/cli_harness.h"
#include "tests/unit_fixture.h"
#include "util/io.h"

namespace topocal::testing_cli {
namespace {

namespace fs = std::filesystem;

// The budgets: a record at most 5 MB, its report at most 1 MB; and a regression bound on the record near its
// measured size (0.48 MB; the report measured 0.80 MB).
constexpr std::uintmax_t kRecordBudgetBytes = 5'000'000, kReportBudgetBytes = 1'000'000;
constexpr std::uintmax_t kRecordRegressionBytes = 750'000;
constexpr int kRecordMaps = 16;  // 2 cases x 2 stages x 4 maps

std::uintmax_t TreeBytes(const fs::path& dir, int* csv_maps, int* png_maps) {
  std::uintmax_t bytes = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    bytes += e.file_size();
    if (e.path().parent_path().filename() == "maps") {
      *csv_maps += e.path().extension() == ".csv" ? 1 : 0;
      *png_maps += e.path().extension() == ".png" ? 1 : 0;
    }
  }
  return bytes;
}

class UnitRecordSize : public TempDirTest {
 protected:
  std::string Calibrate(const std::string& out, const std::string& extra) const {
    const std::string in = UnitInputsDir();
    return fmt::format(
        "unit calibrate --serial SN-0001 --target {0}/target.yaml --images {0}/view.png --reference-sphere "
        "{0}/sphere.png --sphere-radius-mm {1} --device {0}/device.json --uncertainty 4 --out {2} {3}",
        in, kUnitSphereRadiusMm, out, extra);
  }
};

// The record's maps don't depend on the sensor (400 px maps of 241 x 241 grids), so this unit's record is the size
// of a full-sensor one (measured at 4000 x 3000: 0.47 MB, report 0.75 MB): 51.6 MB with the 16 CSV grids of ~3 MB
// each it always held, its report 4.9 MB of embedded true-colour PNGs.
TEST_F(UnitRecordSize, ARecordAndItsReportStayWithinTheirBudgets) {
  const fs::path out = dir_ / "units" / "SN-0001";
  const auto r = RunTopocal(Calibrate(out.string(), ""));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  int csv = 0, png = 0;
  const std::uintmax_t record = TreeBytes(out, &csv, &png);
  EXPECT_EQ(png, kRecordMaps);
  EXPECT_EQ(csv, 0);
  EXPECT_LE(record, kRecordBudgetBytes) << record;
  EXPECT_LE(record, kRecordRegressionBytes) << record;
  const std::string html = (dir_ / "SN-0001.html").string();
  const auto rep = RunTopocal(fmt::format("report --unit {} --out {}", out.string(), html));
  ASSERT_EQ(rep.exit_code, 0) << rep.output;
  EXPECT_LE(fs::file_size(html), kReportBudgetBytes) << fs::file_size(html);
  // Every map is still in it, as a picture.
  const std::string text = util::ReadFile(html);
  int embedded = 0;
  for (auto at = text.find("data:image/png;base64,"); at != std::string::npos;
       at = text.find("data:image/png;base64,", at + 1)) {
    ++embedded;
  }
  EXPECT_EQ(embedded, kRecordMaps);
}

// --map-csv keeps the numbers behind every picture: one CSV per PNG, listed and verified like every record file.
TEST_F(UnitRecordSize, MapCsvAddsTheGridBehindEveryPicture) {
  const fs::path out = dir_ / "units" / "SN-0001";
  const auto r = RunTopocal(Calibrate(out.string(), "--map-csv"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  int csv = 0, png = 0;
  TreeBytes(out, &csv, &png);
  EXPECT_EQ(csv, kRecordMaps);
  EXPECT_EQ(png, kRecordMaps);
  const std::string grid = util::ReadFile((out / "maps" / "paper_corrected_axial_power.csv").string());
  EXPECT_EQ(grid.substr(0, grid.find('\n')), "x_mm,y_mm,value_D");
  const std::string unit_json = util::ReadFile((out / "unit.json").string());
  EXPECT_NE(unit_json.find("maps/paper_corrected_axial_power.csv"), std::string::npos);
  const auto rep = RunTopocal(fmt::format("report --unit {} --out {}", out.string(), (dir_ / "r.html").string()));
  EXPECT_EQ(rep.exit_code, 0) << rep.output;  // the CSVs are verified by their digests with the rest
}

// unit calibrate-batch --map-csv: every unit of the batch keeps its grids; without it, none does.
TEST_F(UnitRecordSize, BatchMapCsvReachesEveryUnit) {
  const std::string in = UnitInputsDir();
  const fs::path batch = dir_ / "line";
  for (const char* serial : {"SN-A", "SN-B"}) {
    fs::create_directories(batch / serial);
    util::WriteFileAtomic((batch / serial / "unit-inputs.json").string(),
                          fmt::format(R"({{"serial": "{0}", "target": "{1}/target.yaml", "images": "{1}/view.png",)"
                                      R"( "reference_sphere": "{1}/sphere.png", "sphere_radius_mm": {2},)"
                                      R"( "device": "{1}/device.json"}})",
                                      serial, in, kUnitSphereRadiusMm));
  }
  for (const bool csv : {true, false}) {
    const fs::path out = dir_ / (csv ? "with" : "without");
    const auto r = RunTopocal(fmt::format("unit calibrate-batch {} --out {} --uncertainty 4 {}", batch.string(),
                                          out.string(), csv ? "--map-csv" : ""));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    for (const char* serial : {"SN-A", "SN-B"}) {
      int csv_maps = 0, png_maps = 0;
      TreeBytes(out / serial, &csv_maps, &png_maps);
      EXPECT_EQ(png_maps, kRecordMaps) << serial;
      EXPECT_EQ(csv_maps, csv ? kRecordMaps : 0) << serial;
    }
  }
}

}  // namespace
}  // namespace topocal::testing_cli

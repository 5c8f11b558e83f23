// Reading a unit record: a complete record reads back; each kind of bad record is refused with one line naming the
// file and the key.
#include "report/unit_record_reader.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "tests/report/record_fixture.h"
#include "util/io.h"

namespace topocal::report {
namespace {

namespace fs = std::filesystem;
using testing::MakeRecord;
using testing::FreshDir;

// The message of the InputError that reading `dir` throws ("" if it does not throw).
std::string ReadError(const std::string& dir) {
  try {
    ReadUnitRecord(dir);
  } catch (const util::InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << "one line: " << what;
    return what;
  }
  return "";
}

TEST(UnitRecordReader, ReadsACompleteRecord) {
  const auto f = MakeRecord(FreshDir("ok"));
  const UnitRecord r = ReadUnitRecord(f.dir);
  EXPECT_EQ(r.serial, "SN-TEST-0001");
  EXPECT_EQ(r.created_utc, testing::kCreatedUtc);
  EXPECT_EQ(r.inputs.size(), 5u);
  EXPECT_EQ(r.files.size(), 7u);  // calibration.yaml, 4 maps, residuals.csv, sphere_spots.csv
  EXPECT_EQ(r.residuals.size(), f.calibration.residuals.size());
  EXPECT_EQ(r.map_png.size(), 4u);
  EXPECT_TRUE(r.map_png.count("sphere_corrected_axial_power.png"));
  EXPECT_EQ(r.calibration.camera.width_px, testing::kWidthPx);
  EXPECT_EQ(r.calibration.model, "seidel");
  ASSERT_TRUE(r.verification.has_value());
  EXPECT_EQ(r.verification->corrected.at("radius_error_mm"),
            f.unit["verification"]["corrected"]["radius_error_mm"].get<double>());
  EXPECT_EQ(r.verification->detected.size(), static_cast<std::size_t>(testing::ComputeChecks().sphere_spots.size()));
  ASSERT_TRUE(r.paper.uncertainty.has_value());
  EXPECT_EQ(r.paper.uncertainty->quantities.at("kx").U,
            f.unit["paper_cornea"]["uncertainty"]["quantities"]["kx"]["U"].get<double>());
  ASSERT_TRUE(r.config && r.topographer_camera);
  EXPECT_EQ(r.topographer_camera->width_px, testing::kWidthPx);
  EXPECT_EQ(r.unit_json_sha256, util::Sha256HexOfFile(f.Path("unit.json")));
}

TEST(UnitRecordReader, OptionalBlocksMayBeAbsent) {
  auto f = MakeRecord(FreshDir("optional"));
  f.unit.erase("verification");
  f.unit["paper_cornea"].erase("uncertainty");
  f.unit["calibration"].erase("seidel");
  f.WriteUnitJson();
  const UnitRecord r = ReadUnitRecord(f.dir);
  EXPECT_FALSE(r.verification.has_value());
  EXPECT_FALSE(r.paper.uncertainty.has_value());
  EXPECT_FALSE(r.seidel_sigma_per_mm2.has_value());
}

// Hostile numbers in unit.json are bad input naming the key (1e999 was exit 1 with nlohmann's message;
// 4294967297 wrapped to 1).
TEST(UnitRecordReader, RefusesHostileNumbersAndDuplicateKeys) {
  auto f = MakeRecord(FreshDir("hostile"));
  const std::string good = f.unit.dump(1);
  const auto write_with = [&](const std::string& from, const std::string& to) {
    std::string text = good;
    const auto at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
    util::WriteFileAtomic(f.Path("unit.json"), text);
    return ReadError(f.dir);
  };
  EXPECT_NE(
      write_with(fmt::format("\"format_version\": {}", kUnitRecordFormatVersion), "\"format_version\": 4294967297")
          .find("unit.json: format_version: must be in ["),
      std::string::npos);
  EXPECT_NE(write_with("\"rms_px\": ", "\"rms_px\": 1e999, \"x\": ").find("unit.json: calibration.rms_px: a number beyond"),
            std::string::npos);
  EXPECT_NE(write_with("\"outliers\": ", "\"outliers\": 1, \"outliers\": ").find("calibration.outliers: given twice"),
            std::string::npos);
  const std::string deep = write_with("\"serial\": ", "\"deep\": " + std::string(100000, '[') + ", \"serial\": ");
  EXPECT_NE(deep.find("unit.json: nested deeper than"), std::string::npos) << deep;
}

TEST(UnitRecordReader, RefusesAMissingDirectory) {
  const std::string dir = FreshDir("gone") + "/nothing";
  EXPECT_NE(ReadError(dir).find("nothing"), std::string::npos);
}

TEST(UnitRecordReader, RefusesAMissingUnitJson) {
  const auto f = MakeRecord(FreshDir("nounit"));
  fs::remove(f.Path("unit.json"));
  const std::string e = ReadError(f.dir);
  EXPECT_NE(e.find("unit.json: missing"), std::string::npos) << e;
}

TEST(UnitRecordReader, RefusesAMissingCalibrationYaml) {
  const auto f = MakeRecord(FreshDir("nocal"));
  fs::remove(f.Path("calibration.yaml"));
  const std::string e = ReadError(f.dir);
  EXPECT_NE(e.find("calibration.yaml: missing"), std::string::npos) << e;
  EXPECT_NE(e.find("incomplete"), std::string::npos) << e;
}

TEST(UnitRecordReader, RefusesARecordThatDoesNotListItsCalibration) {
  auto f = MakeRecord(FreshDir("unlisted"));
  auto& files = f.unit["files"];
  files.erase(std::remove_if(files.begin(), files.end(), [](const auto& x) { return x["name"] == "calibration.yaml"; }),
              files.end());
  f.WriteUnitJson();
  const std::string e = ReadError(f.dir);
  EXPECT_NE(e.find("unit.json: files: 'calibration.yaml' is not listed"), std::string::npos) << e;
}

TEST(UnitRecordReader, RefusesAFileChangedAfterTheRecordWasWritten) {
  const auto f = MakeRecord(FreshDir("tampered"));
  std::ofstream(f.Path("residuals.csv"), std::ios::app) << "0,views/v1.png,999,1,1,0,0,0\n";
  const std::string e = ReadError(f.dir);
  EXPECT_NE(e.find("residuals.csv: SHA-256"), std::string::npos) << e;
  EXPECT_NE(e.find("files["), std::string::npos) << e;
}

TEST(UnitRecordReader, RefusesAListedMapThatIsMissing) {
  const auto f = MakeRecord(FreshDir("nomap"));
  fs::remove(f.Path("maps/paper_corrected_axial_power.png"));
  const std::string e = ReadError(f.dir);
  EXPECT_NE(e.find("maps/paper_corrected_axial_power.png: missing"), std::string::npos) << e;
}

TEST(UnitRecordReader, RefusesAnotherToolVersion) {
  auto f = MakeRecord(FreshDir("version"));
  f.unit["tool_version"] = "0.0.9";
  f.WriteUnitJson();
  const std::string e = ReadError(f.dir);
  EXPECT_NE(e.find("unit.json: tool_version: the record was written by topocal 0.0.9"), std::string::npos) << e;
}

TEST(UnitRecordReader, RefusesAnotherFormatOrFormatVersion) {
  auto f = MakeRecord(FreshDir("format"));
  f.unit["format_version"] = kUnitRecordFormatVersion + 1;
  f.WriteUnitJson();
  EXPECT_NE(ReadError(f.dir).find(
                fmt::format("unit.json: format_version: {} is not supported", kUnitRecordFormatVersion + 1)),
            std::string::npos);
  f.unit["format"] = "something-else";
  f.WriteUnitJson();
  EXPECT_NE(ReadError(f.dir).find("unit.json: format: 'something-else'"), std::string::npos);
}

// How the calibration's covariance reached the numbers is part of the record: a setting and a method it does not
// know, or a setting and a number of draws that do not go together, are refused by key.
TEST(UnitRecordReader, RefusesAnUncertaintyMethodItDoesNotKnow) {
  auto f = MakeRecord(FreshDir("method"));
  f.unit["settings"]["uncertainty"] = "bootstrap";
  f.WriteUnitJson();
  std::string e = ReadError(f.dir);
  EXPECT_NE(e.find("unit.json: settings.uncertainty: \"bootstrap\" with 8 draws is not an uncertainty setting"),
            std::string::npos)
      << e;
  f.unit["settings"]["uncertainty"] = "linear";  // with the fixture's 8 draws
  f.WriteUnitJson();
  e = ReadError(f.dir);
  EXPECT_NE(e.find("unit.json: settings.uncertainty: \"linear\" with 8 draws"), std::string::npos) << e;
  f.unit["settings"].erase("uncertainty");
  f.WriteUnitJson();
  e = ReadError(f.dir);
  EXPECT_NE(e.find("settings.uncertainty"), std::string::npos) << e;
  f.unit["settings"]["uncertainty"] = "monte-carlo";
  f.unit["verification"]["uncertainty"]["method"] = "bootstrap";
  f.WriteUnitJson();
  e = ReadError(f.dir);
  EXPECT_NE(e.find("verification.uncertainty.method: must be linear or monte-carlo"), std::string::npos) << e;
}

TEST(UnitRecordReader, NamesAMissingOrMistypedKey) {
  auto f = MakeRecord(FreshDir("keys"));
  f.unit["calibration"].erase("rms_px");
  f.WriteUnitJson();
  EXPECT_NE(ReadError(f.dir).find("unit.json: calibration.rms_px: missing"), std::string::npos);

  f = MakeRecord(FreshDir("keys2"));
  f.unit["paper_cornea"]["corrected"]["kx"] = "-0.43";
  f.WriteUnitJson();
  EXPECT_NE(ReadError(f.dir).find("unit.json: paper_cornea.corrected.kx: must be a number"), std::string::npos);

  f = MakeRecord(FreshDir("keys3"));
  f.unit["verification"]["uncertainty"]["quantities"].erase("ry_mm");
  f.WriteUnitJson();
  EXPECT_NE(ReadError(f.dir).find("unit.json: verification.uncertainty.quantities.ry_mm: missing"),
            std::string::npos);

  f = MakeRecord(FreshDir("keys4"));
  f.unit["inputs"][1]["sha256"] = "abc";
  f.WriteUnitJson();
  EXPECT_NE(ReadError(f.dir).find("unit.json: inputs[1].sha256: must be 64 lower-case hex digits"),
            std::string::npos);
}

TEST(UnitRecordReader, RefusesNamesOutsideTheRecord) {
  auto f = MakeRecord(FreshDir("escape"));
  f.unit["files"].push_back({{"name", "../outside.txt"}, {"sha256", std::string(64, '0')}});
  f.WriteUnitJson();
  EXPECT_NE(ReadError(f.dir).find("is not a path inside the record"), std::string::npos);
}

TEST(UnitRecordReader, RefusesMalformedJsonAndResiduals) {
  auto f = MakeRecord(FreshDir("malformed"));
  util::WriteFileAtomic(f.Path("unit.json"), "{\"format\": ");
  EXPECT_NE(ReadError(f.dir).find("unit.json: not valid JSON"), std::string::npos);

  f = MakeRecord(FreshDir("csv"));
  util::WriteFileAtomic(f.Path("residuals.csv"), "view,x\n");
  f.Seal();
  EXPECT_NE(ReadError(f.dir).find("residuals.csv: header"), std::string::npos);

  f = MakeRecord(FreshDir("csv2"));
  util::WriteFileAtomic(f.Path("residuals.csv"),
                        "view,image,corner_id,x_px,y_px,dx_px,dy_px,outlier\n0,v.png,1,10,20,nan,0,0\n");
  f.Seal();
  EXPECT_NE(ReadError(f.dir).find("residuals.csv: line 2: dx_px: not a finite number"), std::string::npos);
}

TEST(UnitRecordReader, RefusesACalibrationOfAnotherImageSize) {
  auto f = MakeRecord(FreshDir("size"));
  f.unit["calibration"]["image_width_px"] = 640;
  f.WriteUnitJson();
  EXPECT_NE(ReadError(f.dir).find("unit.json: calibration.image_width_px: 640 x 3000 px differs"),
            std::string::npos);
}

}  // namespace
}  // namespace topocal::report

// `topocal report` end to end: the report of a complete record, the same bytes twice, and every bad input refused
// with one line, exit 2 and no report file.
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "model/io.h"
#include "tests/cli_harness.h"
#include "tests/report/record_fixture.h"

namespace topocal::report {
namespace {

namespace fs = std::filesystem;
using testing::FreshDir;
using testing::MakeRecord;
using topocal::testing_cli::RunTopocal;

struct Case {
  testing::RecordFixture record;
  std::string out;
};

Case MakeCase(const std::string& name) {
  const std::string dir = FreshDir(name);
  Case c{MakeRecord(dir + "/units/SN-TEST-0001"), dir + "/report.html"};
  return c;
}

// One line on stderr, exit 2, and no report.
void ExpectRefused(const Case& c, const std::string& extra_args, const std::string& expected) {
  const auto run = RunTopocal("report --unit " + c.record.dir + " --out " + c.out + extra_args);
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find(expected), std::string::npos) << run.output;
  EXPECT_EQ(std::count(run.output.begin(), run.output.end(), '\n'), 1) << run.output;
  EXPECT_FALSE(fs::exists(c.out));
  for (const auto& e : fs::directory_iterator(fs::path(c.out).parent_path())) {
    EXPECT_EQ(e.path().filename().string().find(".report.html.tmp"), std::string::npos) << "temporary file left";
  }
}

TEST(ReportCli, WritesTheReportOfACompleteRecordTheSameTwice) {
  const Case c = MakeCase("ok");
  const auto run = RunTopocal("report --unit " + c.record.dir + " --out " + c.out);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("for unit SN-TEST-0001: PASS"), std::string::npos) << run.output;
  const std::string first = model::ReadFile(c.out);
  EXPECT_EQ(first.rfind("<!DOCTYPE html>", 0), 0u);
  ASSERT_EQ(RunTopocal("report --unit " + c.record.dir + " --out " + c.out).exit_code, 0);
  EXPECT_EQ(model::ReadFile(c.out), first);
  // The bundled limits are the defaults: the same page.
  ASSERT_EQ(RunTopocal("report --unit " + c.record.dir + " --out " + c.out + " --limits " + TOPOCAL_SOURCE_DIR +
                       "/data/limits.json")
                .exit_code,
            0);
  const std::string with_file = model::ReadFile(c.out);
  EXPECT_NE(with_file.find("/data/limits.json"), std::string::npos);
}

TEST(ReportCli, RefusesAnIncompleteUnit) {
  Case c = MakeCase("nocal");
  fs::remove(c.record.Path("calibration.yaml"));
  ExpectRefused(c, "", "calibration.yaml: missing");
  c = MakeCase("nounit");
  fs::remove(c.record.Path("unit.json"));
  ExpectRefused(c, "", "unit.json: missing");
}

TEST(ReportCli, RefusesAChangedFile) {
  const Case c = MakeCase("hash");
  std::ofstream(c.record.Path("maps/sphere_corrected_axial_power.png"), std::ios::app) << "x";
  ExpectRefused(c, "", "sphere_corrected_axial_power.png: SHA-256");
}

TEST(ReportCli, RefusesAnotherToolVersion) {
  Case c = MakeCase("version");
  c.record.unit["tool_version"] = "9.9.9";
  c.record.WriteUnitJson();
  ExpectRefused(c, "", "tool_version: the record was written by topocal 9.9.9");
}

TEST(ReportCli, RefusesMalformedLimits) {
  const Case c = MakeCase("limits");
  const std::string limits = fs::path(c.out).parent_path() / "limits.json";
  model::WriteFileAtomic(limits, R"({"format": "topocal-limits", "format_version": 1, "decision_rule": "guarded",
                                     "limits": {}})");
  ExpectRefused(c, " --limits " + limits, "limits.json: limits.calibration_rms_px: missing");
  ExpectRefused(c, " --limits " + limits + ".absent", "limits.json.absent: cannot be opened");
}

TEST(ReportCli, RefusesAMissingOption) {
  const auto run = RunTopocal("report --out x.html");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("--unit"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace topocal::report

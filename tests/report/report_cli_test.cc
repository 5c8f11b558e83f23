// `topocal report` end to end: the report of a complete record, the same bytes twice, and every bad input refused
// with one line, exit 2 and no report file.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <tuple>
#include <vector>

#include "tests/cli_harness.h"
#include "tests/report/record_fixture.h"
#include "util/io.h"

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
  const std::string first = util::ReadFile(c.out);
  EXPECT_EQ(first.rfind("<!DOCTYPE html>", 0), 0u);
  ASSERT_EQ(RunTopocal("report --unit " + c.record.dir + " --out " + c.out).exit_code, 0);
  EXPECT_EQ(util::ReadFile(c.out), first);
  // The bundled limits are the defaults: the same page.
  ASSERT_EQ(RunTopocal("report --unit " + c.record.dir + " --out " + c.out + " --limits " + TOPOCAL_SOURCE_DIR +
                       "/data/limits.json")
                .exit_code,
            0);
  const std::string with_file = util::ReadFile(c.out);
  EXPECT_NE(with_file.find("/data/limits.json"), std::string::npos);
}

// The HTML's verdict attribute, data-verdict="PASS|FAIL" on <body>, and each check row's result.
std::string HtmlVerdict(const std::string& html) {
  const std::string key = "<body data-report-id=\"";
  const std::size_t at = html.find("data-verdict=\"", html.find(key));
  return html.substr(at + 14, 4);
}
std::vector<std::string> HtmlCheckResults(const std::string& html) {
  std::vector<std::string> out;
  for (std::size_t at = html.find("<tr data-check="); at != std::string::npos; at = html.find("<tr data-check=", at + 1)) {
    const std::string row = html.substr(at, html.find("</tr>", at) - at);
    out.push_back(row.find("<td class=\"pass\">PASS</td>") != std::string::npos ? "PASS" : "FAIL");
  }
  return out;
}

// report --json: the same verdict as the page, check by check, for a PASS and for a FAIL.
TEST(ReportCli, JsonVerdictEqualsTheHtmlVerdict) {
  const Case c = MakeCase("json");
  const std::string dir = fs::path(c.out).parent_path().string();
  std::string strict = util::ReadFile(std::string(TOPOCAL_SOURCE_DIR) + "/data/limits.json");
  const std::string key = "\"sphere_radius_error_mm\": {\n      \"max\": 0.05";
  ASSERT_NE(strict.find(key), std::string::npos);
  strict.replace(strict.find(key), key.size(), "\"sphere_radius_error_mm\": {\n      \"max\": 0.00001");
  util::WriteFileAtomic(dir + "/strict.json", strict);
  for (const auto& [limits, expected_exit, expected] :
       {std::tuple{std::string(), 0, "PASS"}, std::tuple{" --limits " + dir + "/strict.json", 3, "FAIL"}}) {
    const auto run = RunTopocal("report --unit " + c.record.dir + " --out " + c.out + " --json " + dir +
                                "/report.json --operator 'A. Tester' --station LINE-2 --ball-certificate B-42 "
                                "--target-certificate T-7 --ball-radius-U-mm 0.0008" + limits);
    ASSERT_EQ(run.exit_code, expected_exit) << run.output;
    const std::string html = util::ReadFile(c.out);
    const auto j = nlohmann::json::parse(util::ReadFile(dir + "/report.json"));
    EXPECT_EQ(j.at("format"), "topocal-report");
    EXPECT_EQ(j.at("verdict"), expected);
    EXPECT_EQ(HtmlVerdict(html), j.at("verdict").get<std::string>());
    EXPECT_NE(html.find("data-report-id=\"" + j.at("report_id").get<std::string>() + "\""), std::string::npos);
    const auto rows = HtmlCheckResults(html);
    ASSERT_EQ(rows.size(), j.at("checks").size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const auto& check = j.at("checks")[i];
      EXPECT_EQ(rows[i], check.at("verdict").get<std::string>()) << check.dump();
      for (const char* field : {"id", "value", "U", "limit", "budget"}) EXPECT_TRUE(check.contains(field)) << field;
    }
    EXPECT_EQ(j.at("decision_rule"), "guarded");
    EXPECT_EQ(j.at("sign_off").at("operator"), "A. Tester");
    EXPECT_EQ(j.at("sign_off").at("ball_certificate_id"), "B-42");
    EXPECT_DOUBLE_EQ(j.at("ball_radius_U_mm").get<double>(), 0.0008);
    EXPECT_EQ(j.at("checks")[1].at("budget").size(), 3u);  // sphere radius: calibration, repeatability, certificate
  }
}

TEST(ReportCli, RefusesAPreviousRecordOfAnotherUnitAndABadCertificateU) {
  Case c = MakeCase("prev");
  auto other = MakeRecord(fs::path(c.out).parent_path().string() + "/units/SN-OTHER");
  other.unit["serial"] = "SN-OTHER";
  other.WriteUnitJson();
  ExpectRefused(c, " --previous " + other.dir, "the previous record is of unit SN-OTHER, not SN-TEST-0001");
  // The unit's own previous record with a number edited in its unit.json: refused like the record itself (its
  // numbers were put on the signed comparison as they stood).
  auto edited = MakeRecord(fs::path(c.out).parent_path().string() + "/units/SN-TEST-0001.previous");
  edited.unit["paper_cornea"]["corrected"]["kx"] = -0.5;
  edited.WriteUnitJson();
  ExpectRefused(c, " --previous " + edited.dir, "paper_cornea.corrected.kx: recorded -0.5, recomputed");
  ExpectRefused(c, " --ball-radius-U-mm -0.1", "--ball-radius-U-mm");
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
  util::WriteFileAtomic(limits, R"({"format": "topocal-limits", "format_version": 1, "decision_rule": "guarded",
                                     "limits": {}})");
  ExpectRefused(c, " --limits " + limits, "limits.json: limits.calibration_rms_px: missing");
  ExpectRefused(c, " --limits " + limits + ".absent", "limits.json.absent: cannot be opened");
}

// unit.json is not covered by the digests it lists: the report recomputes every number its verdict uses from the
// record's files (report/record_check.h), so an edited number is refused, not reported.
TEST(ReportCli, RefusesANumberChangedInUnitJson) {
  for (const auto& [key_path, value, expected] :
       {std::tuple{std::vector<std::string>{"calibration", "rms_px"}, 0.01,
                   "calibration.rms_px: recorded 0.01 px, recomputed"},
        std::tuple{std::vector<std::string>{"verification", "corrected", "radius_error_mm"}, 0.0,
                   "verification.corrected.radius_error_mm: recorded 0, recomputed"},
        std::tuple{std::vector<std::string>{"verification", "uncertainty", "quantities", "radius_mm", "U"}, 1e-6,
                   "verification.uncertainty.quantities.radius_mm.U: recorded 1e-06, recomputed"},
        std::tuple{std::vector<std::string>{"paper_cornea", "corrected", "kx"}, -0.5,
                   "paper_cornea.corrected.kx: recorded -0.5, recomputed"}}) {
    Case c = MakeCase("edited");
    nlohmann::json* j = &c.record.unit;
    for (const auto& k : key_path) j = &(*j)[k];
    ASSERT_TRUE(j->is_number()) << key_path.back();
    *j = value;
    c.record.WriteUnitJson();
    ExpectRefused(c, "", expected);
  }
}

// A record written with `--uncertainty none` ("uncertainty": null) reports: guarded acceptance cannot decide without U
// (FAIL, exit 3, the reason on the page), simple acceptance judges the errors alone.
TEST(ReportCli, ReportsARecordWithoutUncertainty) {
  Case c = MakeCase("nou");
  c.record.unit["settings"]["uncertainty"] = "none";
  c.record.unit["settings"]["uncertainty_samples"] = 0;
  c.record.unit["verification"]["uncertainty"] = nullptr;
  c.record.unit["paper_cornea"]["uncertainty"] = nullptr;
  c.record.WriteUnitJson();
  const auto guarded = RunTopocal("report --unit " + c.record.dir + " --out " + c.out);
  EXPECT_EQ(guarded.exit_code, 3) << guarded.output;
  EXPECT_NE(guarded.output.find("for unit SN-TEST-0001: FAIL"), std::string::npos) << guarded.output;
  // The last line names the failed checks and why.
  EXPECT_NE(guarded.output.find("topocal: unit SN-TEST-0001: FAIL: reference sphere: radius error, corrected |error| "
                                "1.57e-06 mm (no U in the record"),
            std::string::npos)
      << guarded.output;
  EXPECT_NE(util::ReadFile(c.out).find("no U in the record: guarded acceptance cannot decide"), std::string::npos);
  const std::string simple = fs::path(c.out).parent_path() / "simple.json";
  std::string limits = util::ReadFile(std::string(TOPOCAL_SOURCE_DIR) + "/data/limits.json");
  const std::string rule = "\"decision_rule\": \"guarded\"";
  ASSERT_NE(limits.find(rule), std::string::npos);
  limits.replace(limits.find(rule), rule.size(), "\"decision_rule\": \"simple\"");
  util::WriteFileAtomic(simple, limits);
  const auto run = RunTopocal("report --unit " + c.record.dir + " --out " + c.out + " --limits " + simple);
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("for unit SN-TEST-0001: PASS"), std::string::npos) << run.output;
  // The recomputation still holds the record to its numbers: without draws there is nothing to compare U with,
  // but the errors are recomputed.
  c.record.unit["paper_cornea"]["corrected"]["ky"] = -0.2;
  c.record.WriteUnitJson();
  fs::remove(c.out);
  ExpectRefused(c, "", "paper_cornea.corrected.ky: recorded -0.2, recomputed");
}

TEST(ReportCli, RefusesAMissingOption) {
  const auto run = RunTopocal("report --out x.html");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("--unit"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace topocal::report

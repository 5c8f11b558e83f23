// The report in a real browser: Debian's headless Chromium prints it to PDF, screenshots it and dumps the DOM after
// the page's load event, and the test checks what is on the page. Chromium is required (scripts/setup.sh test
// installs it): without it the test FAILS, it does not skip.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/cli_harness.h"
#include "tests/report/chromium.h"
#include "tests/report/record_fixture.h"
#include "tests/unit_fixture.h"
#include "util/io.h"

namespace topocal::report {
namespace {

namespace fs = std::filesystem;
using testing::FreshDir;
using testing::MakeRecord;
using topocal::testing_cli::RunTopocal;
using testing::Chromium;
using testing::FindChromium;
using testing::ShellRun;

constexpr int kWindowWidthPx = 1200, kWindowHeightPx = 3000;
// Enough virtual time for the load event after decoding four small PNGs (they are data: URIs, nothing to fetch).
constexpr int kVirtualTimeBudgetMs = 5000;
// A printed report with embedded maps and three SVG plots is tens of kB; an empty page prints to ~7 kB.
constexpr std::uintmax_t kMinPdfBytes = 20000;
// Page breaks before calibration, sphere, paper and acceptance: at least five A4 pages.
constexpr int kMinPdfPages = 5;
// The PASS banner colour (#2e7d32) must cover at least a banner's area in the screenshot (~1000 x 60 px).
constexpr int kMinBannerPixels = 20000;
constexpr int kBannerColourTolerance = 6;  // per channel, for anti-aliasing / colour management
// A rendered page has text, tables and plots: its grey levels vary far more than a blank one (stddev 0).
constexpr double kMinScreenshotStddev = 10.0;

std::size_t Count(const std::string& haystack, const std::string& needle) {
  std::size_t n = 0;
  for (std::size_t pos = haystack.find(needle); pos != std::string::npos; pos = haystack.find(needle, pos + 1)) ++n;
  return n;
}

TEST(ReportInBrowser, ChromiumRendersPrintsAndShowsTheReport) {
  const std::string chromium = FindChromium();
  ASSERT_FALSE(chromium.empty()) << "headless Chromium is required for this test and was not found at "
                                    "/usr/bin/chromium (install the Debian package `chromium`, as scripts/setup.sh "
                                    "test does, or set TOPOCAL_CHROMIUM)";
  const std::string work = FreshDir("browser");
  const auto record = MakeRecord(work + "/units/SN-TEST-0001");
  const std::string html = work + "/report.html";
  const auto made = RunTopocal("report --unit " + record.dir + " --out " + html);
  ASSERT_EQ(made.exit_code, 0) << made.output;
  const std::string page = util::ReadFile(html);
  const std::string id_key = "data-report-id=\"";
  const std::size_t id_at = page.find(id_key);
  ASSERT_NE(id_at, std::string::npos);
  const std::string report_id = page.substr(id_at + id_key.size(), page.find('"', id_at + id_key.size()) - id_at - id_key.size());
  ASSERT_EQ(report_id.size(), std::string("SN-TEST-0001-").size() + 12) << report_id;
  const std::string url = "file://" + fs::absolute(html).string();
  const std::string pdf = work + "/report.pdf", png = work + "/report.png";

  // The three renderings are independent (own profile each): run them side by side.
  auto print = std::async(std::launch::async, [&] {
    return Chromium(chromium, work, "pdf", "--no-pdf-header-footer --print-to-pdf=" + pdf + " " + url);
  });
  auto shot = std::async(std::launch::async, [&] {
    return Chromium(chromium, work, "png",
                    fmt::format("--screenshot={} --window-size={},{} {}", png, kWindowWidthPx, kWindowHeightPx, url));
  });
  auto dom = std::async(std::launch::async, [&] {
    return Chromium(chromium, work, "dom",
                    fmt::format("--virtual-time-budget={} --dump-dom {}", kVirtualTimeBudgetMs, url));
  });
  const ShellRun printed = print.get(), shown = shot.get(), dumped = dom.get();

  // PDF: there, non-trivial, A4 pages, several of them.
  ASSERT_EQ(printed.exit_code, 0) << printed.output;
  ASSERT_TRUE(fs::exists(pdf)) << printed.output;
  EXPECT_GE(fs::file_size(pdf), kMinPdfBytes);
  const std::string pdf_bytes = util::ReadFile(pdf);
  EXPECT_EQ(pdf_bytes.rfind("%PDF-", 0), 0u);
  // Skia writes each page object as "/Type /Page" (the page tree as "/Type /Pages").
  const int pages = static_cast<int>(Count(pdf_bytes, "/Type /Page") - Count(pdf_bytes, "/Type /Pages"));
  EXPECT_GE(pages, kMinPdfPages);
  // A4 = 595.28 x 841.89 pt (210 x 297 mm) on every page.
  EXPECT_EQ(static_cast<int>(Count(pdf_bytes, "/MediaBox [0 0 594.95996 841.91998]")), pages) << "not A4";
  // "Page n of N" on every page, N the page count (poppler's pdftotext reads the PDF's text back; one form feed
  // ends each page).
  const ShellRun text = testing::Shell("pdftotext -layout " + pdf + " - 2>&1");
  ASSERT_EQ(text.exit_code, 0) << "pdftotext (Debian poppler-utils, installed by scripts/setup.sh test): "
                               << text.output;
  EXPECT_EQ(static_cast<int>(Count(text.output, "\f")), pages);
  std::size_t page_start = 0;
  for (int n = 1; n <= pages; ++n) {
    const std::size_t page_end = text.output.find('\f', page_start);
    ASSERT_NE(page_end, std::string::npos);
    const std::string one_page = text.output.substr(page_start, page_end - page_start);
    EXPECT_NE(one_page.find(fmt::format("Page {} of {}", n, pages)), std::string::npos) << "page " << n;
    page_start = page_end + 1;
  }
  // Tables never break inside a token that fits a line: the limits' keys print whole (they printed "sphere_rad" /
  // "ius_error_" / "mm" on three lines).
  for (const char* key : {"calibration_rms_px", "sphere_radius_error_mm", "sphere_power_error_D",
                          "paper_radius_error_mm", "paper_conic_error"}) {
    EXPECT_NE(text.output.find(key), std::string::npos) << key;
  }
  EXPECT_NE(text.output.find("Sign-off"), std::string::npos);
  EXPECT_NE(text.output.find("Appendix A: provenance"), std::string::npos);

  // DOM after the load event: the id, the serial, the verdict, every embedded image decoded.
  ASSERT_EQ(dumped.exit_code, 0) << dumped.output;
  const std::string& d = dumped.output;
  EXPECT_NE(d.find("data-images-decoded=\"4/4\""), std::string::npos) << "embedded PNG maps not decoded";
  EXPECT_NE(d.find("<title>topocal QA report " + report_id), std::string::npos);
  EXPECT_NE(d.find("id=\"report-id\">" + report_id), std::string::npos);
  EXPECT_NE(d.find("class=\"print-header\">topocal QA report <span class=\"report-id\">" + report_id),
            std::string::npos);
  EXPECT_NE(d.find("SN-TEST-0001"), std::string::npos);
  EXPECT_NE(d.find("id=\"verdict\" class=\"banner pass\" data-verdict=\"PASS\">PASS"), std::string::npos);
  EXPECT_EQ(Count(d, "<svg class=\"plot\""), 3u);
  EXPECT_EQ(Count(d, "<tr data-check="), 3u);
  EXPECT_EQ(Count(d, "<tr data-informative="), 4u);

  // Screenshot: loads, the window's size, not blank, and the green PASS banner is on it.
  ASSERT_EQ(shown.exit_code, 0) << shown.output;
  const cv::Mat shot_img = cv::imread(png, cv::IMREAD_COLOR);
  ASSERT_FALSE(shot_img.empty()) << png;
  EXPECT_EQ(shot_img.cols, kWindowWidthPx);
  EXPECT_EQ(shot_img.rows, kWindowHeightPx);
  cv::Mat grey;
  cv::cvtColor(shot_img, grey, cv::COLOR_BGR2GRAY);
  cv::Scalar mean, stddev;
  cv::meanStdDev(grey, mean, stddev);
  EXPECT_GT(stddev[0], kMinScreenshotStddev) << "blank screenshot";
  const cv::Scalar pass_bgr(0x32, 0x7d, 0x2e), tol(kBannerColourTolerance, kBannerColourTolerance,
                                                    kBannerColourTolerance);
  cv::Mat banner;
  cv::inRange(shot_img, pass_bgr - tol, pass_bgr + tol, banner);
  EXPECT_GT(cv::countNonZero(banner), kMinBannerPixels) << "no PASS banner on the rendered page";
  // Three Chromium profiles are megabytes: keep them only to look at a failure.
  if (!HasFailure()) fs::remove_all(work);
}

// The whole line: `topocal unit calibrate` on rendered images of a unit (tests/unit_fixture.h), `topocal report`
// on the record it wrote, and the page in the browser: the real record's sixteen maps decoded, the verdict shown.
TEST(ReportInBrowser, AUnitCalibratedFromImagesReportsAndRendersEndToEnd) {
  const std::string chromium = FindChromium();
  ASSERT_FALSE(chromium.empty()) << "headless Chromium is required (Debian package `chromium`)";
  const std::string in = topocal::testing_cli::UnitInputsDir();
  const std::string work = FreshDir("endtoend");
  const std::string unit = work + "/units/SN-E2E-0001", html = work + "/SN-E2E-0001.html";
  const auto calibrated = RunTopocal(fmt::format(
      "unit calibrate --serial SN-E2E-0001 --target {0}/target.yaml --images {0}/view.png --reference-sphere "
      "{0}/sphere.png --sphere-radius-mm {1} --device {0}/device.json --uncertainty 8 --out {2}",
      in, topocal::testing_cli::kUnitSphereRadiusMm, unit));
  ASSERT_EQ(calibrated.exit_code, 0) << calibrated.output;
  const auto reported = RunTopocal("report --unit " + unit + " --out " + html);
  ASSERT_EQ(reported.exit_code, 0) << reported.output;  // this unit passes every default limit once corrected
  EXPECT_NE(reported.output.find("for unit SN-E2E-0001: PASS"), std::string::npos) << reported.output;

  const ShellRun dumped = Chromium(chromium, work, "dom",
                                   fmt::format("--virtual-time-budget={} --dump-dom file://{}", kVirtualTimeBudgetMs,
                                               fs::absolute(html).string()));
  ASSERT_EQ(dumped.exit_code, 0) << dumped.output;
  const std::string& d = dumped.output;
  // 2 cases (sphere, paper) x 2 stages x 4 maps, all decoded.
  EXPECT_NE(d.find("data-images-decoded=\"16/16\""), std::string::npos) << "embedded maps not all decoded";
  EXPECT_NE(d.find("data-verdict=\"PASS\""), std::string::npos);
  EXPECT_NE(d.find("SN-E2E-0001-"), std::string::npos);  // the report id
  EXPECT_EQ(Count(d, "<svg class=\"plot\""), 3u);

  // Printed: every uncertainty budget on one page, its heading with its last row ("expanded"); the budgets used to
  // print their heading and first rows on one page and the rest on the next.
  const std::string pdf = work + "/report.pdf";
  const ShellRun printed = Chromium(chromium, work, "pdf",
                                    "--no-pdf-header-footer --print-to-pdf=" + pdf + " file://" + fs::absolute(html).string());
  ASSERT_EQ(printed.exit_code, 0) << printed.output;
  const ShellRun text = testing::Shell("pdftotext -layout " + pdf + " - 2>&1");
  ASSERT_EQ(text.exit_code, 0) << text.output;
  int budgets = 0, page = 1, heading_page = 0;
  std::size_t line_start = 0;
  while (line_start < text.output.size()) {
    const std::size_t end = std::min(text.output.find('\n', line_start), text.output.size());
    const std::string line = text.output.substr(line_start, end - line_start);
    page += static_cast<int>(Count(line, "\f"));
    const std::size_t first = line.find_first_not_of(" \f");
    if (first != std::string::npos && line.compare(first, 18, "Uncertainty budget") == 0) heading_page = page, ++budgets;
    if (first != std::string::npos && line.compare(first, 8, "expanded") == 0) {
      EXPECT_EQ(page, heading_page) << "budget " << budgets << " split across pages";
    }
    line_start = end + 1;
  }
  EXPECT_EQ(budgets, 2);

  // Limits this unit cannot meet: the report is still written, says FAIL, and the exit code is 3.
  const std::string strict = work + "/strict.json";
  std::string limits = util::ReadFile(std::string(TOPOCAL_SOURCE_DIR) + "/data/limits.json");
  const std::string rms_key = "\"calibration_rms_px\": {\n      \"max\": 0.5";
  ASSERT_NE(limits.find(rms_key), std::string::npos);
  limits.replace(limits.find(rms_key), rms_key.size(), "\"calibration_rms_px\": {\n      \"max\": 0.001");
  util::WriteFileAtomic(strict, limits);
  fs::remove(html);
  const auto failed = RunTopocal("report --unit " + unit + " --out " + html + " --limits " + strict);
  EXPECT_EQ(failed.exit_code, 3) << failed.output;
  EXPECT_NE(failed.output.find("for unit SN-E2E-0001: FAIL"), std::string::npos) << failed.output;
  EXPECT_NE(util::ReadFile(html).find("data-verdict=\"FAIL\""), std::string::npos);
  if (!HasFailure()) fs::remove_all(work);
}

}  // namespace
}  // namespace topocal::report

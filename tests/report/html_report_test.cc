// The HTML of the report: its id everywhere it must be, every section, the embedded maps, nothing fetched from
// outside, no NaN, the same bytes for the same record.
#include "report/html_report.h"

#include <algorithm>
#include <cctype>
#include <regex>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "plot/svg.h"
#include "plot/svg_charts.h"
#include "tests/report/record_fixture.h"
#include "util/io.h"

namespace topocal::report {
namespace {

using testing::FreshDir;
using testing::MakeRecord;

// The record with hand-picked check numbers (tests/report/record_fixture.h): the rule, the budget and the page are
// functions of the numbers, checked here against hand computations.
testing::RecordFixture MakeHandRecord(const std::string& dir) {
  testing::RecordFixture f = MakeRecord(dir);
  testing::UseHandPickedChecks(f);
  return f;
}
using plot::EscapeXml;
using plot::NiceFloor;
using plot::QuiverOptions;
using plot::SvgQuiver;

std::size_t Count(const std::string& haystack, const std::string& needle) {
  std::size_t n = 0;
  for (std::size_t pos = haystack.find(needle); pos != std::string::npos; pos = haystack.find(needle, pos + 1)) ++n;
  return n;
}

TEST(Base64, Rfc4648Vectors) {
  EXPECT_EQ(Base64(""), "");
  EXPECT_EQ(Base64("f"), "Zg==");
  EXPECT_EQ(Base64("fo"), "Zm8=");
  EXPECT_EQ(Base64("foo"), "Zm9v");
  EXPECT_EQ(Base64("foob"), "Zm9vYg==");
  EXPECT_EQ(Base64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(Base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(Base64(std::string("\xff\x00\x80", 3)), "/wCA");
}

// Every byte value at every position and every padding case, decoded back by a reference decoder written from
// RFC 4648 section 4 (not by the encoder's library); and a large input in one line (EVP_EncodeUpdate, the streaming
// API, would break it every 64 characters, which a data: URI does not allow).
TEST(Base64, EveryByteAndLengthDecodesBackAndLongInputHasNoLineBreaks) {
  static constexpr std::string_view kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto decode = [&](const std::string& text) {
    std::string bytes;
    unsigned bits = 0;
    int count = 0;
    for (const char c : text) {
      if (c == '=') break;
      const auto v = kAlphabet.find(c);
      if (v == std::string_view::npos) return std::string("<bad character>");
      bits = (bits << 6) | static_cast<unsigned>(v);
      count += 6;
      if (count >= 8) {
        count -= 8;
        bytes += static_cast<char>((bits >> count) & 0xff);
      }
    }
    return bytes;
  };
  std::string input;
  for (int n = 0; n < 3 * 256 + 3; ++n) {
    const std::string encoded = Base64(input);
    ASSERT_EQ(encoded.size(), 4 * ((input.size() + 2) / 3)) << n;
    ASSERT_EQ(decode(encoded), input) << n;
    const std::size_t pad = (3 - input.size() % 3) % 3;
    ASSERT_EQ(encoded.find('='), pad == 0 ? std::string::npos : encoded.size() - pad) << n;
    input += static_cast<char>((n * 97 + 13) % 256);  // every byte value, in a scrambled order
  }
  const std::string large(1 << 20, '\x5a');
  const std::string encoded = Base64(large);
  EXPECT_EQ(encoded.find_first_of("\r\n"), std::string::npos);
  EXPECT_EQ(encoded.size(), 4 * ((large.size() + 2) / 3));
  EXPECT_EQ(encoded.substr(0, 8), "WlpaWlpa");
}

TEST(SvgPlot, NiceFloorAndEscaping) {
  EXPECT_DOUBLE_EQ(NiceFloor(7.3), 5);
  EXPECT_DOUBLE_EQ(NiceFloor(2.0), 2);
  EXPECT_DOUBLE_EQ(NiceFloor(0.0199), 0.01);
  EXPECT_DOUBLE_EQ(NiceFloor(0), 1);
  EXPECT_EQ(EscapeXml("a<b & \"c\">'"), "a&lt;b &amp; &quot;c&quot;&gt;&#39;");
  QuiverOptions o;
  o.image_width_px = o.image_height_px = 10;
  EXPECT_THROW(SvgQuiver({{0, 0, std::nan(""), 0, false}}, o), util::InputError);
}

TEST(SvgPlot, QuiverHasOneArrowPerVectorAndAScaleBar) {
  QuiverOptions o;
  o.image_width_px = 400;
  o.image_height_px = 300;
  o.title = "t";
  const std::string svg = SvgQuiver({{10, 10, 1, 0, false}, {200, 150, 0, -2, true}}, o);
  EXPECT_EQ(Count(svg, "<polygon"), 2u);
  EXPECT_EQ(Count(svg, "class=\"scale-bar\""), 1u);
  // Longest 2 px, 6 % of 400 px = 24 px: magnified x10 (1-2-5 floor of 12); bar of 1 px.
  EXPECT_NE(svg.find("1 px (vectors magnified \u00d710; longest 2 px)"), std::string::npos) << svg;
}

class HtmlReportTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    fixture_ = new testing::RecordFixture(MakeHandRecord(FreshDir("html")));
    record_ = new UnitRecord(ReadUnitRecord(fixture_->dir));
    html_ = new std::string(RenderHtmlReport(*record_, ReportInputs{}));
  }
  static void TearDownTestSuite() {
    delete html_;
    delete record_;
    delete fixture_;
  }
  static testing::RecordFixture* fixture_;
  static UnitRecord* record_;
  static std::string* html_;
};
testing::RecordFixture* HtmlReportTest::fixture_ = nullptr;
UnitRecord* HtmlReportTest::record_ = nullptr;
std::string* HtmlReportTest::html_ = nullptr;

TEST_F(HtmlReportTest, ReportIdHashesTheRecordTheLimitsAndTheRule) {
  const ReportInputs in;
  const std::string id = ReportId(*record_, in);
  EXPECT_TRUE(std::regex_match(id, std::regex("SN-TEST-0001-[0-9a-f]{12}"))) << id;
  const std::string text = ReportIdText(*record_, in);
  EXPECT_EQ(id.substr(id.size() - 12), util::Sha256Hex(text).substr(0, 12));
  EXPECT_NE(text.find("unit_json_sha256=" + util::Sha256HexOfFile(fixture_->Path("unit.json"))), std::string::npos);
  EXPECT_EQ(ReportId(*record_, ReportInputs{}), id);  // same inputs, same id
  // Another limit, another rule, another certificate U, another operator: another id.
  ReportInputs limit = in;
  limit.limits.sphere_power_error_D.max = 0.5;
  ReportInputs rule = in;
  rule.limits.rule = DecisionRule::kSimple;
  ReportInputs cert = in;
  cert.budget.ball_radius_U_mm = 0.002;
  ReportInputs signer = in;
  signer.sign_off.operator_name = "A. Tester";
  const std::set<std::string> ids = {id, ReportId(*record_, limit), ReportId(*record_, rule), ReportId(*record_, cert),
                                     ReportId(*record_, signer)};
  EXPECT_EQ(ids.size(), 5u);
  // The limit's prose source is not part of the decision: it does not change the id.
  ReportInputs source = in;
  source.limits.sphere_power_error_D.source = "another wording";
  EXPECT_EQ(ReportId(*record_, source), id);
}

TEST(HtmlReport, APassAndAFailReportOfOneRecordHaveDifferentIds) {
  const auto f = MakeHandRecord(FreshDir("passfail"));
  const UnitRecord rec = ReadUnitRecord(f.dir);
  ReportInputs strict;
  strict.limits.sphere_radius_error_mm.max = 1e-4;  // |radius error| = 5e-4 mm: FAIL
  const std::string pass = RenderHtmlReport(rec, ReportInputs{}), fail = RenderHtmlReport(rec, strict);
  EXPECT_NE(pass.find("data-verdict=\"PASS\""), std::string::npos);
  EXPECT_NE(fail.find("data-verdict=\"FAIL\""), std::string::npos);
  EXPECT_NE(ReportId(rec, ReportInputs{}), ReportId(rec, strict));
  EXPECT_NE(fail.find("data-report-id=\"" + ReportId(rec, strict) + "\""), std::string::npos);
}

TEST_F(HtmlReportTest, IdInTitleHeaderFooterAndBody) {
  const std::string& h = *html_;
  const std::string id = ReportId(*record_, ReportInputs{});
  EXPECT_NE(h.find("<title>topocal QA report " + id), std::string::npos);
  EXPECT_NE(h.find("<div class=\"print-header\">topocal QA report <span class=\"report-id\">" + id), std::string::npos);
  EXPECT_NE(h.find("<div class=\"print-footer\">Report <span class=\"report-id\">" + id), std::string::npos);
  EXPECT_NE(h.find("id=\"report-id\">" + id), std::string::npos);
  // Repeated on every printed page: fixed in print, with page-frame rows reserving their room.
  const std::size_t print_css = h.find("@media print {");
  ASSERT_NE(print_css, std::string::npos);
  EXPECT_NE(h.find(".print-header, .print-footer { display: block; position: fixed;", print_css), std::string::npos);
  EXPECT_NE(h.find("@page { size: A4;"), std::string::npos);
  // Page n of N in the bottom margin of every printed page (CSS paged media margin box).
  EXPECT_NE(h.find("@bottom-right { content: \"Page \" counter(page) \" of \" counter(pages);"), std::string::npos);
  EXPECT_NE(h.find("<thead><tr><td><div class=\"header-space\">"), std::string::npos);
  EXPECT_NE(h.find("record created 2026-11-25T19:00:00Z"), std::string::npos);
}

// The distortion plot's colour bar, its arrows' legend and the caption speak of one region: the measurement field
// when the record gives it (cells beyond its disc have no data, arrows there are not drawn). The bar's top label
// (3 significant digits), the longest arrow and the caption's largest displacement are the same number (the bar
// reached 83.2 px where the caption said 12.69 px).
TEST_F(HtmlReportTest, DistortionPlotColourBarArrowsAndCaptionAgree) {
  ASSERT_TRUE(record_->field_radius_px);
  const std::string& h = *html_;
  const std::size_t at = h.find("Distortion field of the calibrated model");
  ASSERT_NE(at, std::string::npos);
  const std::string svg = h.substr(at, h.find("</svg>", at) - at);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(h, m, std::regex("largest displacement ([0-9.e+-]+) px")));
  const double caption = std::stod(m[1]);
  ASSERT_TRUE(std::regex_search(svg, m, std::regex("font-size=\"10\"[^>]*>([0-9.e+-]+)</text>")));
  const double bar_top = std::stod(m[1]);
  EXPECT_NEAR(bar_top, caption, 0.005 * caption) << bar_top << " vs " << caption;
  ASSERT_TRUE(std::regex_search(svg, m, std::regex("longest ([0-9.e+-]+) px")));
  EXPECT_LE(std::stod(m[1]), caption * 1.005) << m[1];
  EXPECT_NE(svg.find("#dcdcdc"), std::string::npos);  // the corners beyond the field: no data
}

// A short table is never split from its heading nor across pages: each heading followed by a table of at most
// kShortTableRows rows is in a .keep block (break-inside: avoid) that closes right after the table — the uncertainty
// budgets printed heading on one page, half their rows on the next. Longer tables (limits, provenance) may run on:
// their heading stays with their first rows (h3 break-after: avoid, rows unbroken).
TEST_F(HtmlReportTest, AShortTableIsKeptWithItsHeading) {
  constexpr int kShortTableRows = 12;
  const std::string& h = *html_;
  int kept = 0;
  for (std::size_t at = h.find("<h3>"); at != std::string::npos; at = h.find("<h3>", at + 1)) {
    const std::size_t table = h.find("<table", at), end = h.find("</table>", at);
    ASSERT_NE(end, std::string::npos);
    if (h.find("<h3>", at + 1) < table) continue;  // a heading over text only
    const std::string body = h.substr(table, end - table);
    if (Count(body, "<tr") > static_cast<std::size_t>(kShortTableRows)) continue;
    const std::string heading = h.substr(at, h.find("</h3>", at) - at);
    const std::string open = "<div class=\"keep\">";
    EXPECT_EQ(h.compare(at - open.size(), open.size(), open), 0) << heading;
    EXPECT_EQ(h.compare(end, 14, "</table></div>"), 0) << heading;
    ++kept;
  }
  EXPECT_GE(kept, 3);  // the informative rows and the two budgets
  EXPECT_NE(h.find(".keep { break-inside: avoid; }"), std::string::npos);
}

TEST_F(HtmlReportTest, HasEverySection) {
  const std::string& h = *html_;
  for (const char* id : {"id=\"verdict\"", "id=\"identity\"", "id=\"sign-off\"", "id=\"method\"", "id=\"inputs\"",
                         "id=\"calibration\"", "id=\"alpha-note\"",
                         "id=\"seidel-sigma\"", "id=\"residuals\"", "id=\"sphere\"", "id=\"paper\"",
                         "id=\"acceptance\"", "id=\"checks\""}) {
    EXPECT_NE(h.find(id), std::string::npos) << id;
  }
  EXPECT_NE(h.find("data-verdict=\"PASS\">PASS"), std::string::npos);
  EXPECT_NE(h.find("Guarded acceptance (ILAC-G8:09/2019"), std::string::npos);
  EXPECT_EQ(Count(h, "<tr data-check="), 3u);        // calibration RMS, the sphere's radius and power
  EXPECT_EQ(Count(h, "<tr data-informative="), 4u);  // the paper cornea's r_x, r_y, k_x, k_y: not checks
  EXPECT_EQ(Count(h, "<svg class=\"plot\""), 3u);  // per-view RMS, residual vectors, distortion field
  EXPECT_EQ(Count(h, "<rect class=\"bar\""), 1u);  // one view
  // The hashes are in the appendix, after the acceptance section, not on the first pages.
  EXPECT_NE(h.find("Appendix A: provenance"), std::string::npos);
  EXPECT_GT(h.find(record_->unit_json_sha256), h.find("id=\"acceptance\""));
  EXPECT_GT(h.find(record_->files.front().sha256), h.find("id=\"acceptance\""));
  // Sign-off fields not given are printed as such; blank lines for signature and date.
  EXPECT_NE(h.find("<td data-field=\"operator\"><span class=\"undefined\">not given</span>"), std::string::npos);
  EXPECT_EQ(Count(h, "<td class=\"blank\"></td>"), 2u);
  // alpha of the sphere: undefined in all four columns, not a number.
  const std::size_t alpha = h.find("<tr data-quantity=\"alpha_deg\">");
  ASSERT_NE(alpha, std::string::npos);
  const std::string alpha_row = h.substr(alpha, h.find("</tr>", alpha) - alpha);
  EXPECT_EQ(Count(alpha_row, ">undefined<"), 4u) << alpha_row;
  // The budgets of the two sphere checks (calibration, repeatability, certificate).
  EXPECT_EQ(Count(h, "<table class=\"data budget\""), 2u);
  EXPECT_NE(h.find("data-budget=\"sphere_radius_error_mm\""), std::string::npos);
  EXPECT_NE(h.find("data-budget=\"sphere_power_error_D\""), std::string::npos);
  EXPECT_NE(h.find("<td>reference ball certificate</td>"), std::string::npos);
  EXPECT_NE(h.find("no repeated images in the record"), std::string::npos);
  // Every input and record file with its digest.
  for (const auto& in : record_->inputs) EXPECT_NE(h.find(in.sha256), std::string::npos) << in.path;
  for (const auto& f : record_->files) EXPECT_NE(h.find(f.sha256), std::string::npos) << f.name;
  // Parameters with U (k = 2): k1 fitted, fx fixed.
  const std::size_t k1 = h.find("<td>k1</td><td class=\"num\">");
  ASSERT_NE(k1, std::string::npos);
  const std::string fitted_u = "</td><td class=\"num\">\u00b1 ";
  EXPECT_EQ(h.substr(h.find("</td>", k1 + 30), fitted_u.size()), fitted_u);
  EXPECT_NE(h.find("<td>fx</td><td class=\"num\">4642.857</td><td class=\"num\">\u2014</td><td>fixed"),
            std::string::npos);
  EXPECT_NE(h.find("Seidel \u03c3 = <strong>"), std::string::npos);
  // Before/after tables of both cases with the Monte Carlo U.
  EXPECT_NE(h.find("<td>radius error (mm)</td>"), std::string::npos);
  EXPECT_NE(h.find("<td>power error (D)</td>"), std::string::npos);
  EXPECT_NE(h.find("-0.4302</td><td class=\"num\">-0.0002</td><td class=\"num\">0.0002 \u00b1 0.003</td>"),
            std::string::npos);
  // Model adequacy: both rows in both tables, the record's values in the stages' columns, and how to read
  // them under each table.
  EXPECT_EQ(Count(h, "<td>model adequacy: slope residual / expected noise</td>"), 2u);
  EXPECT_EQ(Count(h, "<td>model adequacy: structured part / expected noise</td>"), 2u);
  EXPECT_NE(h.find("<td>model adequacy: slope residual / expected noise</td><td class=\"num\"></td><td "
                   "class=\"num\">3.40</td><td class=\"num\">0.04</td>"),
            std::string::npos);
  EXPECT_EQ(Count(h, "<p class=\"note adequacy\">"), 2u);
}

TEST_F(HtmlReportTest, MapsAreEmbeddedAndNothingIsFetched) {
  const std::string& h = *html_;
  EXPECT_EQ(Count(h, "<img "), 4u);
  EXPECT_EQ(Count(h, "src=\"data:image/png;base64,"), 4u);
  EXPECT_NE(h.find(Base64(record_->map_png.at("paper_corrected_axial_power.png"))), std::string::npos);
  for (const char* external : {"http://", "https://", "src=\"/", "src=\"file:", "href=", "url(", "@import", "<link",
                               "<iframe", "<object", "<embed", "//cdn"}) {
    EXPECT_EQ(h.find(external), std::string::npos) << external;
  }
  EXPECT_EQ(Count(h, "src=\""), 4u);  // only the four data: URIs
}

// The words of the page outside its base64 payloads (std::regex would overflow the stack on a page this long).
std::vector<std::string> Words(const std::string& html) {
  std::vector<std::string> words;
  std::string word;
  for (std::size_t i = 0; i < html.size(); ++i) {
    if (html.compare(i, 7, "base64,") == 0) {
      i = html.find('"', i);
      if (i == std::string::npos) break;
    }
    const unsigned char c = html[i];
    if (std::isalnum(c)) {
      word += static_cast<char>(std::tolower(c));
    } else if (!word.empty()) {
      words.push_back(word);
      word.clear();
    }
  }
  return words;
}

TEST_F(HtmlReportTest, NoNanAndDeterministic) {
  for (const std::string& w : Words(*html_)) {
    EXPECT_TRUE(w != "nan" && w != "inf" && w != "infinity") << w;
  }
  EXPECT_EQ(RenderHtmlReport(ReadUnitRecord(fixture_->dir), ReportInputs{}), *html_);
}

TEST(HtmlReport, SignOffAndPreviousCalibrationAreShown) {
  const auto f = MakeHandRecord(FreshDir("now"));
  auto g = MakeHandRecord(FreshDir("before"));
  g.unit["created_utc"] = "2025-11-25T19:00:00Z";
  g.unit["verification"]["corrected"]["radius_error_mm"] = 0.03;  // drifted by 0.0295 mm, beyond U
  g.WriteUnitJson();
  const UnitRecord rec = ReadUnitRecord(f.dir), prev = ReadUnitRecord(g.dir);
  ReportInputs in;
  in.sign_off = {"A. Tester", "LINE-2", "BALL-7.8-0042", "TGT-2026-007"};
  in.budget.ball_radius_U_mm = 0.0006;
  in.previous = &prev;
  const std::string h = RenderHtmlReport(rec, in);
  EXPECT_NE(h.find("<td data-field=\"operator\">A. Tester</td>"), std::string::npos);
  EXPECT_NE(h.find("<td data-field=\"station\">LINE-2</td>"), std::string::npos);
  EXPECT_NE(h.find("<td data-field=\"ball-certificate\">BALL-7.8-0042</td>"), std::string::npos);
  EXPECT_NE(h.find("TGT-2026-007"), std::string::npos);
  EXPECT_NE(h.find("0.0006 mm (certificate)"), std::string::npos);
  EXPECT_NE(h.find("id=\"previous\""), std::string::npos);
  EXPECT_NE(h.find("created 2025-11-25T19:00:00Z"), std::string::npos);
  const std::size_t row = h.find("<td>sphere radius error, corrected</td>", h.find("id=\"previous-table\""));
  ASSERT_NE(row, std::string::npos);
  EXPECT_NE(h.substr(row, h.find("</tr>", row) - row).find("changed beyond U"), std::string::npos);
  // The JSON holds the same comparison, by id, and every check's id is its own.
  const nlohmann::json j = ReportJson(rec, in);
  const auto& comparison = j["previous"]["comparison"];
  const auto sphere = std::find_if(comparison.begin(), comparison.end(),
                                   [](const nlohmann::json& r) { return r["id"] == "sphere_radius_error_mm"; });
  ASSERT_NE(sphere, comparison.end()) << comparison.dump();
  EXPECT_DOUBLE_EQ((*sphere)["previous"].get<double>(), 0.03);
  EXPECT_DOUBLE_EQ((*sphere)["change"].get<double>(),
                   (*sphere)["now"].get<double>() - (*sphere)["previous"].get<double>());
  EXPECT_FALSE((*sphere)["within_U"].get<bool>());
  EXPECT_EQ(comparison.size(), 6u) << comparison.dump();  // RMS, Seidel sigma, sphere radius and power, paper k_x, k_y
  std::set<std::string> ids;
  for (const auto& c : j["checks"]) EXPECT_TRUE(ids.insert(c["id"].get<std::string>()).second) << c["id"];
  EXPECT_EQ(ids.size(), j["checks"].size());
  // Another unit's record is not a previous calibration of this one.
  auto other = MakeHandRecord(FreshDir("other"));
  other.unit["serial"] = "SN-OTHER";
  other.WriteUnitJson();
  const UnitRecord o = ReadUnitRecord(other.dir);
  in.previous = &o;
  EXPECT_THROW(RenderHtmlReport(rec, in), util::InputError);
}

TEST(HtmlReport, FailingRecordSaysFailAndWhy) {
  auto f = MakeHandRecord(FreshDir("fail"));
  f.unit["paper_cornea"]["corrected"]["kx"] = -0.61;  // the uncorrected value: correction did nothing
  f.unit.erase("verification");
  f.WriteUnitJson();
  const std::string h = RenderHtmlReport(ReadUnitRecord(f.dir), ReportInputs{});
  EXPECT_NE(h.find("data-verdict=\"FAIL\">FAIL"), std::string::npos);
  EXPECT_NE(h.find("No reference sphere was given"), std::string::npos);
  EXPECT_NE(h.find("not verified: the record has no reference-sphere verification"), std::string::npos);
  // The paper cornea's k_x off by 0.18: shown, beyond its informative threshold, but not a check.
  const std::size_t kx = h.find("<tr data-informative=\"paper_kx_error\">");
  ASSERT_NE(kx, std::string::npos);
  const std::string kx_row = h.substr(kx, h.find("</tr>", kx) - kx);
  EXPECT_NE(kx_row.find("<td class=\"num\">0.18</td>"), std::string::npos) << kx_row;
  EXPECT_NE(kx_row.find("beyond"), std::string::npos) << kx_row;
  EXPECT_NE(h.find("1 of 3 checks passed"), std::string::npos);
  // The first page names the failed checks, right under the banner (before the identity section).
  const std::size_t failed = h.find("<ul id=\"failed-checks\"");
  ASSERT_NE(failed, std::string::npos);
  EXPECT_LT(failed, h.find("id=\"identity\""));
  const std::string list = h.substr(failed, h.find("</ul>", failed) - failed);
  EXPECT_NE(list.find("FAILED: reference sphere: radius error, corrected (not verified"), std::string::npos) << list;
  EXPECT_NE(list.find("FAILED: reference sphere: power error, corrected (not verified"), std::string::npos) << list;
  EXPECT_EQ(list.find("paper cornea"), std::string::npos) << list;
  EXPECT_EQ(std::count(list.begin(), list.end(), '\n'), 3) << list;  // the <ul> line and two failed checks
}


// A control chart of values the line can produce — identical to the last ulp, a 1e308 among ordinary ones, one NaN —
// draws in bounded time and memory with finite coordinates (a tick loop stepping below the values' rounding would
// never advance, and allocate until std::bad_alloc).
TEST(SvgControlChart, DegenerateValuesDrawABoundedChart) {
  for (const std::vector<double>& values :
       {std::vector<double>(8, 2.208e-06), std::vector<double>{2.208e-06, std::nextafter(2.208e-06, 1.0), 2.208e-06},
        std::vector<double>{0.3, 0.31, 1e308, 0.29}, std::vector<double>{0.3, std::nan(""), 0.31}}) {
    plot::ControlChartPlot p;
    p.title = "calibration rms";
    p.value_label = "px";
    p.values = values;
    const std::string svg = plot::SvgControlChart(p);
    EXPECT_LT(svg.size(), 200000u);
    EXPECT_EQ(svg.find("nan"), std::string::npos);
    EXPECT_EQ(svg.find("inf"), std::string::npos);
  }
}

}  // namespace
}  // namespace topocal::report

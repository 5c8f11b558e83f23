// `topocal design --svg`: the printable null screen end to end.
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/cli_harness.h"

namespace {

namespace fs = std::filesystem;

using topocal::testing_cli::Run;
using topocal::testing_cli::RunTopocal;

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A small XML well-formedness check: tags nest and close, attribute quotes pair up, '<' and '&' in text are
// escaped. Returns an empty string or the first problem.
std::string XmlProblem(const std::string& xml) {
  std::vector<std::string> open;
  size_t i = 0;
  while (i < xml.size()) {
    if (xml[i] == '&') {
      const size_t semi = xml.find(';', i);
      if (semi == std::string::npos || semi - i > 8) return "bare '&' at " + std::to_string(i);
      i = semi + 1;
      continue;
    }
    if (xml[i] != '<') {
      ++i;
      continue;
    }
    if (xml.compare(i, 4, "<!--") == 0) {
      const size_t end = xml.find("-->", i);
      if (end == std::string::npos) return "unclosed comment";
      i = end + 3;
      continue;
    }
    const size_t end = xml.find('>', i);
    if (end == std::string::npos) return "unclosed tag at " + std::to_string(i);
    const std::string tag = xml.substr(i + 1, end - i - 1);
    i = end + 1;
    if (tag.find('<') != std::string::npos) return "'<' inside a tag: " + tag.substr(0, 40);
    if (std::count(tag.begin(), tag.end(), '"') % 2 != 0) return "unpaired quote in " + tag.substr(0, 40);
    if (tag.front() == '?') {
      if (tag.back() != '?') return "bad processing instruction";
      continue;
    }
    const bool closing = tag.front() == '/';
    const bool self_closing = tag.back() == '/';
    const std::string name = tag.substr(closing ? 1 : 0, tag.find_first_of(" \t\n/", closing ? 1 : 0) - (closing ? 1 : 0));
    if (name.empty()) return "empty tag name";
    if (closing) {
      if (open.empty() || open.back() != name) return "</" + name + "> does not close <" + (open.empty() ? "" : open.back()) + ">";
      open.pop_back();
    } else if (!self_closing) {
      open.push_back(name);
    }
  }
  if (!open.empty()) return "<" + open.back() + "> never closed";
  return "";
}

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

class DesignSvg : public topocal::testing_cli::TempDirTest {};

TEST_F(DesignSvg, WritesAWellFormedOneToOneSheetWithEverySpot) {
  const auto r = RunTopocal("design --config " + paper_ + " --out " + Path("t.csv") + " --svg " + Path("ns.svg"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string svg = Slurp(Path("ns.svg"));
  EXPECT_EQ(XmlProblem(svg), "");
  // Millimetre document: width/height in mm and a viewBox of the same numbers, so 1 user unit = 1 mm on paper.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(svg, m, std::regex(R"re(width="([0-9.]+)mm" height="([0-9.]+)mm" viewBox="0 0 ([0-9.]+) ([0-9.]+)")re")));
  EXPECT_EQ(m[1].str(), m[3].str());
  EXPECT_EQ(m[2].str(), m[4].str());
  const double width = std::stod(m[1].str()), height = std::stod(m[2].str());
  // The paper's development (outer rim ~92 mm, 67 deg sector) fits on A4 portrait's printable area.
  EXPECT_LT(width, 190.0);
  EXPECT_LT(height, 277.0);
  // One filled outline per spot (624 for the paper), plus the halves of outlines the seam cuts.
  EXPECT_EQ(Count(svg, "<path id=\"spot-"), 624 + Count(svg, "-seam\" d="));
  EXPECT_NE(svg.find("<path id=\"spot-12-95\""), std::string::npos);
  EXPECT_NE(svg.find("paper, 624 spots"), std::string::npos);
  EXPECT_NE(svg.find("id=\"cut-line\""), std::string::npos);
  EXPECT_NE(svg.find("id=\"fold-line\""), std::string::npos);
  EXPECT_NE(svg.find("width=\"10.000\""), std::string::npos);  // the 10 mm scale bar
  EXPECT_NE(svg.find(">10 mm<"), std::string::npos);
  // Every outline coordinate lies on the page.
  const std::regex coord(R"(([ML])([-0-9.]+),([-0-9.]+))");
  int points = 0;
  for (size_t p = svg.find("<path id=\"spot-"); p != std::string::npos; p = svg.find("<path id=\"spot-", p + 1)) {
    const std::string d = svg.substr(p, svg.find("/>", p) - p);
    for (auto it = std::sregex_iterator(d.begin(), d.end(), coord); it != std::sregex_iterator(); ++it) {
      const double x = std::stod((*it)[2].str()), y = std::stod((*it)[3].str());
      EXPECT_TRUE(x >= 0 && x <= width && y >= 0 && y <= height) << x << "," << y;
      ++points;
    }
  }
  EXPECT_GE(points, 624 * 64);
  // Written atomically: nothing but the two outputs in the directory (no temporary left behind).
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 2);
}

// A keyed screen (ideal_image.orientation_key): the target CSV leaves the key's three gaps out, as the SVG does (it
// listed all 624, so a screen built from the CSV was silently unkeyed), and says so.
TEST_F(DesignSvg, TheTargetCsvLeavesTheOrientationKeysGapsOutAsTheSheetDoes) {
  std::string config = Slurp(paper_);
  const size_t at = config.find("\"ideal_image\": {");
  ASSERT_NE(at, std::string::npos);
  config.insert(at + std::string("\"ideal_image\": {").size(), "\"orientation_key\": true, ");
  std::ofstream(Path("keyed.json")) << config;
  const auto r = RunTopocal("design --config " + Path("keyed.json") + " --out " + Path("t.csv") + " --svg " +
                            Path("ns.svg"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("designed 621 target points (0 failed, 3 left out as the orientation key)"),
            std::string::npos)
      << r.output;
  const std::string csv = Slurp(Path("t.csv"));
  EXPECT_EQ(Count(csv, "\n"), 1 + 621);  // header + the printed spots
  const std::string svg = Slurp(Path("ns.svg"));
  EXPECT_EQ(Count(svg, "<path id=\"spot-"), 621 + Count(svg, "-seam\" d="));
  // The same spots in both: every CSV row's id is drawn.
  std::istringstream rows(csv);
  std::string row;
  std::getline(rows, row);  // header
  while (std::getline(rows, row)) {
    const auto comma = row.find(',', row.find(',') + 1);
    const std::string id = row.substr(0, comma);
    const std::string path_id = "<path id=\"spot-" + id.substr(0, id.find(',')) + "-" + id.substr(id.find(',') + 1) + "\"";
    EXPECT_NE(svg.find(path_id), std::string::npos) << row;
  }
}

TEST_F(DesignSvg, UnwritableSvgPathIsBadInputWithoutPartialFile) {
  const std::string bad = Path("no-such-dir/ns.svg");
  const auto r = RunTopocal("design --config " + paper_ + " --out " + Path("t.csv") + " --svg " + bad);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(bad), std::string::npos) << r.output;
  // Only the error line: the CSV is published with the SVG or not at all.
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_FALSE(fs::exists(Path("t.csv")));
  EXPECT_FALSE(fs::exists(bad));
  EXPECT_FALSE(fs::exists(dir_ / "no-such-dir"));
}

TEST(XmlCheck, CatchesMalformedDocuments) {
  EXPECT_EQ(XmlProblem("<a><b/></a>"), "");
  EXPECT_NE(XmlProblem("<a><b></a>"), "");
  EXPECT_NE(XmlProblem("<a x=\"1></a>"), "");
  EXPECT_NE(XmlProblem("<a>1 & 2</a>"), "");
  EXPECT_NE(XmlProblem("<a>"), "");
}

}  // namespace

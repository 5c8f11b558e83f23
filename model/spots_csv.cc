#include "model/spots_csv.h"

#include <fmt/format.h>

#include <cmath>
#include <set>
#include <sstream>

#include "util/io.h"

namespace topocal::model {

std::vector<model::PlaneSpot> ReadSpotsCsv(const std::string& path) {
  const std::string text = util::ReadFile(path);
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  bool header = false;
  std::vector<model::PlaneSpot> rows;
  std::set<model::SpotId> seen;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (!header) {
      if (line != "ring,index,x_mm,y_mm") {
        throw util::InputError(fmt::format("{}:{}: expected header 'ring,index,x_mm,y_mm'", path, line_no));
      }
      header = true;
      continue;
    }
    model::PlaneSpot r;
    char c1 = 0, c2 = 0, c3 = 0;
    std::istringstream ls(line);
    // Judged before the rest is read: a number out of range (1e309) sets failbit and reads as the largest double,
    // and reaching the line's end must not excuse it.
    const bool numbers =
        !(ls >> r.id.ring >> c1 >> r.id.index >> c2 >> r.position_mm.x() >> c3 >> r.position_mm.y()).fail();
    std::string rest;
    ls >> rest;
    if (!numbers || c1 != ',' || c2 != ',' || c3 != ',' || !rest.empty() || !std::isfinite(r.position_mm.x()) ||
        !std::isfinite(r.position_mm.y())) {
      throw util::InputError(fmt::format("{}:{}: expected 'ring,index,x_mm,y_mm' numbers", path, line_no));
    }
    if (r.id.ring < 1 || r.id.index < 0) {
      throw util::InputError(fmt::format("{}:{}: ring must be >= 1 and index >= 0", path, line_no));
    }
    if (!seen.insert(r.id).second) {
      throw util::InputError(fmt::format("{}:{}: spot ({}, {}) appears twice", path, line_no, r.id.ring, r.id.index));
    }
    rows.push_back(r);
  }
  if (!header) throw util::InputError(fmt::format("{}: empty file (no header)", path));
  return rows;
}

std::string SpotsCsv(const std::vector<model::ImageSpot>& spots) {
  std::string out = "ring,index,x_mm,y_mm\n";
  for (const auto& s : spots) {
    out += fmt::format("{},{},{},{}\n", s.id.ring, s.id.index, s.position_mm.x(), s.position_mm.y());
  }
  return out;
}

}  // namespace topocal::model

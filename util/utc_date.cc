#include "util/utc_date.h"

#include <fmt/format.h>

#include <cctype>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <string>

#include "util/io.h"

namespace topocal::util {

std::string FileDateUtc() {
  std::time_t t = std::time(nullptr);
  if (const char* epoch = std::getenv("SOURCE_DATE_EPOCH"); epoch && *epoch) {
    // Digits only (no sign, no spaces) and at most 12 of them: year 33658 at the most, within gmtime's range.
    const std::size_t n = std::strlen(epoch);
    bool digits = n <= 12;
    for (std::size_t i = 0; digits && i < n; ++i) digits = std::isdigit(static_cast<unsigned char>(epoch[i])) != 0;
    if (!digits) {
      throw InputError(
          fmt::format("SOURCE_DATE_EPOCH '{:.40}': not a non-negative integer of at most 12 digits", epoch));
    }
    t = static_cast<std::time_t>(std::strtoll(epoch, nullptr, 10));
  }
  std::tm tm{};
  if (gmtime_r(&t, &tm) == nullptr) throw InputError("SOURCE_DATE_EPOCH: outside the range of a calendar date");
  char buf[40];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

bool IsIsoUtcDate(std::string_view s) {
  static constexpr std::string_view kShape = "dddd-dd-ddTdd:dd:ddZ";
  if (s.size() != kShape.size()) return false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const bool digit = std::isdigit(static_cast<unsigned char>(s[i])) != 0;
    if (kShape[i] == 'd' ? !digit : s[i] != kShape[i]) return false;
  }
  const auto field = [&](std::size_t at, std::size_t n) { return std::atoi(std::string(s.substr(at, n)).c_str()); };
  std::tm tm{};
  tm.tm_year = field(0, 4) - 1900;
  tm.tm_mon = field(5, 2) - 1;
  tm.tm_mday = field(8, 2);
  tm.tm_hour = field(11, 2);
  tm.tm_min = field(14, 2);
  tm.tm_sec = field(17, 2);
  // timegm normalises an impossible date (Feb 30 -> Mar 2): a real one comes back as it went in.
  std::tm back{};
  const std::time_t t = timegm(&tm);
  if (gmtime_r(&t, &back) == nullptr) return false;
  char buf[40];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &back);
  return s == buf;
}

}  // namespace topocal::util

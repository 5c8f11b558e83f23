#include "util/utc_date.h"

#include <fmt/format.h>

#include <cctype>
#include <cstdlib>
#include <cstring>
#include <ctime>

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

}  // namespace topocal::util

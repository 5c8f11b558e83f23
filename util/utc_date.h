#pragma once
// The date every written file carries (unit record, calibration file, fleet database): now, or SOURCE_DATE_EPOCH
// when it is set — the reproducible-builds convention (https://reproducible-builds.org/specs/source-date-epoch/),
// so that a rerun with the same inputs can be compared byte for byte.
#include <string>
#include <string_view>

namespace topocal::util {

// ISO 8601 UTC ("2026-12-01T23:59:59Z"). Throws util::InputError naming SOURCE_DATE_EPOCH when it is set but is
// not a non-negative decimal integer of at most 12 digits (bad input, exit 2).
std::string FileDateUtc();

// Whether `s` is a date as FileDateUtc writes it: "YYYY-MM-DDTHH:MM:SSZ", a real calendar date and time (no
// 2026-02-30, no 24:00:00; a leap second's :60 is refused too, as gmtime never writes it).
bool IsIsoUtcDate(std::string_view s);

}  // namespace topocal::util

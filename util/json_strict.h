#pragma once
// ParseJsonStrict (util/json_section.h) with a size limit of the caller's: for files topocal writes itself and reads
// back, which grow with the work they hold (a harness shard holds ~265 bytes per case: a million cases in one shard
// is ~265 MB, beyond the 64 MiB a configuration may have). Every other check is the same: nesting depth, a key given
// twice, numbers beyond double's range. A header of its own so that the readers of configurations, which include
// json_section.h, do not depend on it.
#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>

namespace topocal::util {

nlohmann::json ParseJsonStrictUpTo(const std::string& text, const std::string& origin, std::size_t max_bytes);

}  // namespace topocal::util

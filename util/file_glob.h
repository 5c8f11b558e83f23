#pragma once
// Expanding a glob(3) pattern given on the command line (quoted, so the shell leaves it alone).
#include <string>
#include <vector>

namespace topocal::util {

// The matching paths, sorted. Throws util::InputError "OPTION 'PATTERN': ..." when nothing matches.
std::vector<std::string> Glob(const std::string& pattern, const std::string& option = "--images");

}  // namespace topocal::util

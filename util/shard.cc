#include "util/shard.h"

#include <fmt/format.h>

#include "util/io.h"

namespace topocal::util {

ShardSpec ParseShardSpec(const std::string& text) {
  const auto slash = text.find('/');
  auto parse = [&](const std::string& part, int* out) {
    if (part.empty() || part.size() > 9) return false;
    for (const char c : part) {
      if (c < '0' || c > '9') return false;
    }
    *out = std::stoi(part);
    return true;
  };
  ShardSpec s;
  if (slash == std::string::npos || !parse(text.substr(0, slash), &s.index) ||
      !parse(text.substr(slash + 1), &s.count)) {
    throw util::InputError(fmt::format("--shard: must be i/N with integers 0 <= i < N (got \"{}\")", text));
  }
  if (s.count < 1 || s.index >= s.count) {
    throw util::InputError(fmt::format("--shard: must be i/N with 0 <= i < N and N >= 1 (got \"{}\")", text));
  }
  return s;
}

}  // namespace topocal::util

#include "util/file_glob.h"

#include <fmt/format.h>
#include <glob.h>

#include "util/io.h"

namespace topocal::util {

std::vector<std::string> Glob(const std::string& pattern, const std::string& option) {
  glob_t g{};
  const int rc = ::glob(pattern.c_str(), GLOB_ERR | GLOB_TILDE, nullptr, &g);
  std::vector<std::string> paths;
  if (rc == 0) {
    for (size_t i = 0; i < g.gl_pathc; ++i) paths.emplace_back(g.gl_pathv[i]);
  }
  globfree(&g);
  if (rc == GLOB_NOMATCH || paths.empty())
    throw util::InputError(fmt::format("{} '{}': no file matches", option, pattern));
  if (rc != 0) throw util::InputError(fmt::format("{} '{}': cannot be expanded", option, pattern));
  return paths;  // glob(3) sorts them
}

}  // namespace topocal::util

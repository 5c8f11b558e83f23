#include "tools/data_dir.h"

#include <fmt/format.h>

#include <cstdlib>
#include <filesystem>
#include <system_error>

#include "util/io.h"

namespace topocal::tools {

std::string DataDir() {
  namespace fs = std::filesystem;
  if (const char* env = std::getenv("TOPOCAL_DATA_DIR"); env && *env) {
    if (!fs::is_directory(env)) throw util::InputError(fmt::format("TOPOCAL_DATA_DIR={}: not a directory", env));
    return env;
  }
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path data = exe.parent_path().parent_path() / "share" / "topocal" / "data";
    if (fs::is_directory(data)) return data.string();
    throw util::InputError(
        fmt::format("the bundled data is not at {} (next to the executable): set TOPOCAL_DATA_DIR", data.string()));
  }
  throw util::InputError("cannot locate the executable to find the bundled data: set TOPOCAL_DATA_DIR");
}

}  // namespace topocal::tools

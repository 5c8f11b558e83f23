// topocal-sweep — the commands that touch no image: `--version` and `sweep` without --correct or --maps, which
// `topocal` (launcher.cc) hands to this program. OpenCV's shared libraries and their dependencies are most of a
// process' start-up (docs/performance.md: `--version` took ~34 ms of CPU, nearly all of it the dynamic loader and page
// faults for 56 libraries), so this program is linked only against model, topo, Ceres and fmt. A sweep that needs
// OpenCV (NeedsFullCli), and any other command line it is given, is handed on unchanged to topocal-full (main.cc) with
// execv: the same process, so the same process id, signals, standard streams and exit code.
#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string_view>
#include <system_error>
#include <vector>

#include "tools/cli_app.h"
#include "tools/commands.h"

namespace {

// Whether this program runs the command line itself: `--version`, or `sweep` without a help flag (the sweep's
// --correct and --maps are found when parsed: NeedsFullCli).
bool RunsHere(int argc, char** argv) {
  std::vector<std::string_view> args;
  for (int i = 1; i < argc; ++i) {
    if (std::string_view(argv[i]) != "--quiet") args.emplace_back(argv[i]);
  }
  if (args.size() == 1 && args[0] == "--version") return true;
  if (args.empty() || args[0] != "sweep") return false;
  for (const auto a : args) {
    if (a == "-h" || a == "--help" || a == "--help-all") return false;
  }
  return true;
}

// topocal-full is installed in <prefix>/<libexecdir>, beside this program; the build tree mirrors that layout
// (tools/CMakeLists.txt).
[[noreturn]] void ExecFullCli(char** argv) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  const fs::path full = exe.parent_path().parent_path() / TOPOCAL_INSTALL_LIBEXECDIR / "topocal-full";
  if (ec) {
    fmt::print(stderr, "topocal: cannot locate this executable (/proc/self/exe: {}) to run topocal-full\n",
               ec.message());
    std::exit(1);
  }
  std::fflush(nullptr);
  execv(full.c_str(), argv);
  fmt::print(stderr, "topocal: cannot run {}: {} (install topocal with `cmake --install`)\n", full.string(),
             std::strerror(errno));
  std::exit(1);
}

}  // namespace

int main(int argc, char** argv) {
  if (!RunsHere(argc, argv)) ExecFullCli(argv);
  CLI::App app{topocal::tools::kAppDescription};
  topocal::tools::SetUpApp(app);
  topocal::tools::AddSweepCommand(app, nullptr);
  try {
    return topocal::tools::RunApp(app, argc, argv);
  } catch (const topocal::tools::NeedsFullCli&) {
    ExecFullCli(argv);
  }
}

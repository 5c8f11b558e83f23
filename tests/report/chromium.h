#pragma once
// Headless Chromium for the report tests: find it, run it under a timeout with its own HOME and profile.
#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "util/io.h"

namespace topocal::report::testing {

// Each Chromium run is killed after this long (a hung browser must fail the test, not hang CI); a cold start on
// the 2-core machine takes about 2 s.
inline constexpr int kChromiumTimeoutS = 60;

inline std::string FindChromium() {
  if (const char* env = std::getenv("TOPOCAL_CHROMIUM"); env && *env) return env;
  for (const char* candidate : {"/usr/bin/chromium", "/usr/bin/chromium-browser"}) {
    if (::access(candidate, X_OK) == 0) return candidate;
  }
  return "";
}

struct ShellRun {
  int exit_code = -1;
  std::string output;
};

inline ShellRun Shell(const std::string& cmd) {
  ShellRun r;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 65536> buf;
  while (std::size_t n = fread(buf.data(), 1, buf.size(), pipe)) r.output.append(buf.data(), n);
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

// Headless Chromium with its own HOME and profile (it writes both), killed after the timeout. stderr (D-Bus noise
// on a machine without a session bus) goes to a log that a failure prints.
inline ShellRun Chromium(const std::string& chromium, const std::string& work, const std::string& name, const std::string& args) {
  const std::string home = work + "/home-" + name, profile = work + "/profile-" + name, log = work + "/" + name + ".log";
  std::filesystem::create_directories(home);
  const std::string cmd =
      fmt::format("env HOME={} timeout -k 5 {} {} --headless --no-sandbox --disable-gpu --no-first-run "
                  "--no-default-browser-check --disable-extensions --hide-scrollbars --user-data-dir={} {} 2>{}",
                  home, kChromiumTimeoutS, chromium, profile, args, log);
  ShellRun r = Shell(cmd);
  if (r.exit_code != 0) {
    std::string err;
    try {
      err = util::ReadFile(log);
    } catch (const std::exception&) {
    }
    r.output += "\n[chromium stderr]\n" + err;
  }
  return r;
}

}  // namespace topocal::report::testing

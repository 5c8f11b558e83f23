#pragma once
// Running the `topocal` binary from a test: its exit code and everything it printed (stdout and stderr together).
// TOPOCAL_EXE is defined by the test's CMakeLists.txt.
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace topocal::testing_cli {

struct Run {
  int exit_code;
  std::string output;  // stdout and stderr together
};

inline Run RunTopocal(const std::string& args) {
  const std::string cmd = std::string(TOPOCAL_EXE) + " " + args + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return {-1, "popen failed"};
  std::string out;
  std::array<char, 4096> buf;
  while (size_t n = fread(buf.data(), 1, buf.size(), pipe)) out.append(buf.data(), n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), out};
}

}  // namespace topocal::testing_cli

#pragma once
// Running the `topocal` binary from a test: its exit code and everything it printed (stdout and stderr together).
// TOPOCAL_EXE is defined by the test's CMakeLists.txt.
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

namespace topocal::testing_cli {

struct Run {
  int exit_code;
  std::string output;  // stdout and stderr together
};

// `env`: variable assignments (NAME=value ...) for this run only.
inline Run RunTopocal(const std::string& args, const std::string& env = "") {
  const std::string cmd = env + (env.empty() ? "" : " ") + TOPOCAL_EXE + " " + args + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return {-1, "popen failed"};
  std::string out;
  std::array<char, 4096> buf;
  while (size_t n = fread(buf.data(), 1, buf.size(), pipe)) out.append(buf.data(), n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), out};
}

// Starts `topocal ARGS` in the background (its output discarded) and returns its process id: for tests that send
// it a signal. Reap it with WaitTopocal.
inline pid_t SpawnTopocal(const std::string& args) {
  const std::string cmd = std::string("exec ") + TOPOCAL_EXE + " " + args + " >/dev/null 2>&1";
  const char* argv[] = {"/bin/sh", "-c", cmd.c_str(), nullptr};
  pid_t pid = -1;
  if (posix_spawn(&pid, "/bin/sh", nullptr, nullptr, const_cast<char* const*>(argv), environ) != 0) return -1;
  return pid;
}

// Waits for a spawned process; its exit code, or 128 + the signal that ended it.
inline int WaitTopocal(pid_t pid) {
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// A test with an empty directory of its own (under the system temp dir, named by the process and the test), removed
// afterwards: the fixture every command-line test starts from. Derived fixtures that override SetUp call
// TempDirTest::SetUp() first.
class TempDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           ("topocal_" + std::string(info->test_suite_name()) + "_" + std::to_string(::getpid()) + "_" + info->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    if (!dir_.empty()) std::filesystem::remove_all(dir_);
  }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  void Write(const std::string& name, const std::string& text) const { std::ofstream(Path(name)) << text; }
  // The bytes of a file in the test's directory (empty if it cannot be read).
  std::string Bytes(const std::string& name) const {
    std::ifstream in(Path(name), std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }

  std::filesystem::path dir_;
#ifdef TOPOCAL_SOURCE_DIR
  const std::string paper_ = std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json";
#endif
};

}  // namespace topocal::testing_cli

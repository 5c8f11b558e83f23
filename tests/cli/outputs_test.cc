// Outputs are whole or absent, and an output path is handled for what it is — a symbolic link is written
// through (the link stays), a FIFO or a device is written into (never replaced by a regular file), "-" is refused;
// several outputs of one run are published together; a signal removes whatever is staged.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "tests/cli_harness.h"
#include "util/io.h"

namespace {

namespace fs = std::filesystem;

using topocal::testing_cli::RunTopocal;
using topocal::testing_cli::SpawnTopocal;
using topocal::testing_cli::WaitTopocal;

class Outputs : public topocal::testing_cli::TempDirTest {
 protected:
  std::string Design(const std::string& out) const { return "design --config " + paper_ + " --out " + out; }
  // Every entry of the test directory whose name says it is staging (".NAME.tmp-", ".staging-", ".tmp-").
  std::vector<std::string> Leftovers() const {
    std::vector<std::string> found;
    for (const auto& e : fs::recursive_directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      if (name.find(".tmp") != std::string::npos || name.find(".staging-") != std::string::npos) found.push_back(name);
    }
    return found;
  }
};

TEST_F(Outputs, ASymlinkIsWrittenThroughAndStaysALink) {
  std::ofstream(Path("real.csv")) << "old";
  fs::create_symlink("real.csv", Path("link.csv"));
  const auto r = RunTopocal(Design(Path("link.csv")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::is_symlink(Path("link.csv")));
  EXPECT_EQ(topocal::util::ReadFile(Path("real.csv")).rfind("ring,index,x_mm,y_mm,z_mm\n", 0), 0u);
  // A dangling link: its target is created.
  fs::create_symlink("new.csv", Path("dangling.csv"));
  ASSERT_EQ(RunTopocal(Design(Path("dangling.csv"))).exit_code, 0);
  EXPECT_TRUE(fs::is_symlink(Path("dangling.csv")));
  EXPECT_TRUE(fs::is_regular_file(Path("new.csv")));
  EXPECT_TRUE(Leftovers().empty());
}

TEST_F(Outputs, AFifoIsWrittenIntoNotReplaced) {
  ASSERT_EQ(::mkfifo(Path("pipe").c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] { received = topocal::util::ReadFile(Path("pipe")); });  // blocks until the writer opens
  const auto r = RunTopocal(Design(Path("pipe")));
  reader.join();
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(received.rfind("ring,index,x_mm,y_mm,z_mm\n", 0), 0u);
  EXPECT_GT(received.size(), 10000u);  // 624 rows
  EXPECT_TRUE(fs::is_fifo(Path("pipe")));
  EXPECT_TRUE(Leftovers().empty());
}

// A FIFO nobody reads once blocked the run for ever in open(2). It now waits at most the stream timeout, then
// fails naming the FIFO; other outputs of the run are published before the streams, as documented.
TEST_F(Outputs, AFifoWithoutAReaderTimesOutWithALine) {
  ASSERT_EQ(::mkfifo(Path("pipe").c_str(), 0600), 0);
  const auto start = std::chrono::steady_clock::now();
  const auto r = RunTopocal(Design(Path("pipe")), "TOPOCAL_STREAM_TIMEOUT_S=0.5");
  const double waited_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_EQ(r.output, "topocal: " + Path("pipe") + ": cannot be written: no reader opened the FIFO within 0.5 s\n");
  EXPECT_GE(waited_s, 0.5);
  EXPECT_TRUE(fs::is_fifo(Path("pipe")));
  const auto bad = RunTopocal(Design(Path("pipe")), "TOPOCAL_STREAM_TIMEOUT_S=forever");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("TOPOCAL_STREAM_TIMEOUT_S: 'forever' is not a number of seconds"), std::string::npos)
      << bad.output;
  EXPECT_TRUE(Leftovers().empty());
}

TEST_F(Outputs, DevNullStaysADevice) {
  // As root the atomic rename replaced /dev/null with a regular file.
  ASSERT_EQ(RunTopocal(Design("/dev/null")).exit_code, 0);
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
  const auto r = RunTopocal(Design("-"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("-: not an output path"), std::string::npos) << r.output;
  const auto dir = RunTopocal(Design(dir_.string()));
  EXPECT_EQ(dir.exit_code, 2) << dir.output;
  EXPECT_NE(dir.output.find("is a directory"), std::string::npos) << dir.output;
}

TEST_F(Outputs, SeveralOutputsArePublishedTogetherOrNotAtAll) {
  std::ofstream(Path("file")) << "x";
  // The SVG cannot be written (its directory is a file): the CSV, once written first, is absent too.
  const auto r = RunTopocal(Design(Path("t.csv")) + " --svg " + Path("file/screen.svg"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("file/screen.svg"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("t.csv")));
  // A missing directory is an error (a misspelt path), and nothing is created.
  const auto nested = RunTopocal(Design(Path("t.csv")) + " --svg " + Path("new/dir/s.svg"));
  EXPECT_EQ(nested.exit_code, 2) << nested.output;
  EXPECT_NE(nested.output.find("new/dir/s.svg: cannot be written: No such file or directory"), std::string::npos)
      << nested.output;
  EXPECT_FALSE(fs::exists(Path("t.csv")));
  EXPECT_FALSE(fs::exists(Path("new")));
  ASSERT_EQ(RunTopocal(Design(Path("t.csv")) + " --svg " + Path("s.svg")).exit_code, 0);
  EXPECT_TRUE(fs::is_regular_file(Path("t.csv")));
  EXPECT_TRUE(fs::is_regular_file(Path("s.svg")));
  EXPECT_TRUE(Leftovers().empty());
}

TEST_F(Outputs, AFullDiskIsNamed) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full on this system";
  // /dev/full is a character device: written into, and every write fails with ENOSPC.
  const auto r = RunTopocal(Design("/dev/full"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("/dev/full: cannot be written: disk full"), std::string::npos) << r.output;
}

TEST_F(Outputs, SigtermDuringTheHarnessLeavesNothing) {
  // A harness of ~20 s on one core (4,320 cases at ~5 ms; 2026-12-02: the 288-case harness this test used before
  // finished inside the 700 ms once cases got faster); killed while it computes, it leaves neither its output
  // directory nor staging.
  std::ofstream(Path("h.json")) << R"({"design": ")" << paper_ << R"(", "seed": 3,
      "distortion": {"seidel_sigma_per_mm2": {"from": 1e-6, "to": 6.3e-5, "count": 40, "spacing": "log", "both_signs": true}},
      "noise_px": [0.01], "noise_draws": 6, "calibration_errors": [-1, 0, 0.1],
      "limits": {"dk": 0.05, "dP_D": 0.25}})";
  const pid_t pid = SpawnTopocal("harness --config " + Path("h.json") + " --out " + Path("out") + " --jobs 1");
  ASSERT_GT(pid, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  ::kill(pid, SIGTERM);
  EXPECT_EQ(WaitTopocal(pid), 128 + SIGTERM);  // ended by the signal, re-raised after the cleanup
  EXPECT_FALSE(fs::exists(Path("out")));
  EXPECT_TRUE(Leftovers().empty());
}

TEST_F(Outputs, SigtermWhileSweepWritesItsMapsLeavesNoPartialSet) {
  // Killed while the maps are being written (their staging directory exists), the sweep leaves neither a partial
  // set of maps nor its JSON.
  const pid_t pid = SpawnTopocal("sweep --config " + paper_ + " --json " + Path("sweep.json") + " --maps " + Path("maps"));
  ASSERT_GT(pid, 0);
  bool staging = false;
  for (int i = 0; i < 60000 && !staging; ++i) {  // up to 60 s
    for (const auto& e : fs::directory_iterator(dir_)) {
      if (e.path().filename().string().rfind(".maps.staging-", 0) == 0) staging = true;
    }
    if (!staging) ::usleep(1000);
  }
  EXPECT_TRUE(staging) << "the maps were never staged";
  ::kill(pid, SIGTERM);
  const int code = WaitTopocal(pid);
  if (code == 0) {  // finished before the signal arrived: then the set must be whole
    EXPECT_TRUE(fs::exists(Path("sweep.json")));
    EXPECT_TRUE(fs::exists(Path("maps")));
  } else {
    EXPECT_EQ(code, 128 + SIGTERM);
    EXPECT_FALSE(fs::exists(Path("maps")));
    EXPECT_FALSE(fs::exists(Path("sweep.json")));
  }
  EXPECT_TRUE(Leftovers().empty());
}

}  // namespace

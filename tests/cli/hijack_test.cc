// Outputs that cannot be hijacked or aimed at the run's own inputs (docs/robustness.md): staging under unpredictable
// names created exclusively, an output naming one of the run's inputs refused with nothing written, a verb's outputs
// published together, a unit record
// written by one run at a time, what a killed writer left cleared by the next writer and skipped by `fleet ingest`,
// and a file-size limit ending the run with one line instead of SIGXFSZ.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <string>

#include "report/unit_record_writer.h"
#include "tests/cli_harness.h"
#include "util/io.h"

namespace {

namespace fs = std::filesystem;
using topocal::testing_cli::RunTopocal;

class Hijack : public topocal::testing_cli::TempDirTest {
 protected:
  // Entries of the test directory whose names say they are staging or leftovers.
  int Leftovers() const {
    int n = 0;
    for (const auto& e : fs::recursive_directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      n += name.find(".tmp-") != std::string::npos || name.find(".staging-") != std::string::npos ||
           name.find(".old-") != std::string::npos;
    }
    return n;
  }
};

TEST_F(Hijack, StagingNamesAreUnpredictableAndCreatedExclusively) {
  // Two staging directories for the same output in one process: different 64-bit tokens, neither of the old
  // sequential form ".maps.staging-PID-N" a link could be planted at.
  std::set<std::string> names;
  for (int i = 0; i < 2; ++i) {
    topocal::util::StagedOutputs out;
    const fs::path staging = out.AddDirectory(Path("maps"));
    names.insert(staging.filename().string());
    struct stat st {};
    ASSERT_EQ(::lstat(staging.c_str(), &st), 0);
    EXPECT_TRUE(S_ISDIR(st.st_mode)) << "a real directory, not a link";
    EXPECT_TRUE(std::regex_match(staging.filename().string(), std::regex(R"(\.maps\.staging-\d+-[0-9a-f]{16})")))
        << staging;
  }
  EXPECT_EQ(names.size(), 2u);
  EXPECT_EQ(Leftovers(), 0);
}

TEST_F(Hijack, AnOutputThatIsOneOfTheRunsInputsIsRefused) {
  // The configuration the run reads, given again as its output (by another name: a link).
  fs::copy_file(paper_, Path("c.json"));
  fs::create_symlink(Path("c.json"), Path("alias.json"));
  const std::string before = Bytes("c.json");
  const auto r = RunTopocal("design --config " + Path("c.json") + " --out " + Path("alias.json"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("is also an input of this run"), std::string::npos) << r.output;
  EXPECT_EQ(Bytes("c.json"), before);
  // detect --out naming its own image.
  const std::string data = std::string(TOPOCAL_SOURCE_DIR) + "/data/";
  ASSERT_EQ(RunTopocal("render-spots --config " + paper_ + " --device " + data + "device.json --bits 8 --out " +
                       Path("eye.png"))
                .exit_code,
            0);
  const std::string image = Bytes("eye.png");
  const auto d = RunTopocal("detect --config " + paper_ + " --device " + data + "device.json --image " +
                            Path("eye.png") + " --out " + Path("eye.png"));
  EXPECT_EQ(d.exit_code, 2) << d.output;
  EXPECT_NE(d.output.find("eye.png: is also an input of this run"), std::string::npos) << d.output;
  EXPECT_EQ(Bytes("eye.png"), image);
  EXPECT_EQ(Leftovers(), 0);
}

TEST_F(Hijack, AVerbsOutputsArePublishedTogetherOrNotAtAll) {
  // The second output cannot be written (its directory is missing): the first, written on its own before, is absent.
  const std::string data = std::string(TOPOCAL_SOURCE_DIR) + "/data/";
  const auto render = RunTopocal("render-spots --config " + paper_ + " --device " + data + "device.json --bits 8 " +
                                 "--out " + Path("eye.png") + " --truth " + Path("missing/truth.csv"));
  EXPECT_EQ(render.exit_code, 2) << render.output;
  EXPECT_FALSE(fs::exists(Path("eye.png")));
  ASSERT_EQ(RunTopocal("render-spots --config " + paper_ + " --device " + data + "device.json --bits 8 --out " +
                       Path("eye.png"))
                .exit_code,
            0);
  const auto detect = RunTopocal("detect --config " + paper_ + " --device " + data + "device.json --image " +
                                 Path("eye.png") + " --out " + Path("d.csv") + " --json " + Path("missing/d.json"));
  EXPECT_EQ(detect.exit_code, 2) << detect.output;
  EXPECT_NE(detect.output.find("missing/d.json"), std::string::npos) << detect.output;
  EXPECT_FALSE(fs::exists(Path("d.csv")));
  EXPECT_EQ(Leftovers(), 0);
}

TEST_F(Hijack, OneWriterOfARecordAtATime) {
  topocal::report::UnitRecordWriter first(Path("units/SN-1"));
  try {
    topocal::report::UnitRecordWriter second(Path("units/SN-1"));
    FAIL() << "a second writer of the same record was let in";
  } catch (const topocal::util::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("another topocal run is writing this record"), std::string::npos) << e.what();
  }
  topocal::report::UnitRecordWriter other(Path("units/SN-2"));  // another record is not held up
  first.Commit({{"serial", "SN-1"}});
  EXPECT_TRUE(fs::is_regular_file(Path("units/SN-1/unit.json")));
}

TEST_F(Hijack, WhatAKilledWriterLeftIsClearedAndSkipped) {
  // SIGKILL between CommitDirectory's two renames leaves the old record aside and no record; at any other moment,
  // a staging folder beside the record.
  fs::create_directories(Path("units/SN-1.old-4242"));
  std::ofstream(Path("units/SN-1.old-4242/unit.json")) << "{\"serial\": \"SN-1\"}";
  fs::create_directories(Path("units/SN-1.tmp-4243-0123456789abcdef/maps"));
  EXPECT_TRUE(topocal::report::IsRecordLeftover(Path("units/SN-1.tmp-4243-0123456789abcdef/")));
  EXPECT_TRUE(topocal::report::IsRecordLeftover(Path("units/SN-1.old-4242")));
  EXPECT_FALSE(topocal::report::IsRecordLeftover(Path("units/SN-1")));
  EXPECT_FALSE(topocal::report::IsRecordLeftover(Path("units/SN.tmp-line-7")));  // a serial may contain ".tmp-"
  // fleet ingest skips them with a line (here nothing else is left to ingest: refused).
  const auto r = RunTopocal("fleet ingest --db " + Path("f.db") + " " + Path("units/SN-1.tmp-4243-0123456789abcdef/"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("skipped: a staging folder a killed run left"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("f.db")));
  {
    // The next writer of the record puts the set-aside record back and removes the staging folder.
    topocal::report::UnitRecordWriter next(Path("units/SN-1"));
    EXPECT_TRUE(fs::is_regular_file(Path("units/SN-1/unit.json")));
    EXPECT_FALSE(fs::exists(Path("units/SN-1.old-4242")));
    EXPECT_FALSE(fs::exists(Path("units/SN-1.tmp-4243-0123456789abcdef")));
  }
  EXPECT_EQ(Leftovers(), 0);
}

TEST_F(Hijack, AFileSizeLimitEndsTheRunWithOneLineAndNothingBehind) {
  // ulimit -f 1: one block of 1024 bytes. The design's CSV is larger; the default SIGXFSZ would kill the run with
  // its staging file behind.
  const auto d = RunTopocal("design --config " + paper_ + " --out " + Path("t.csv"),
                                                  "ulimit -f 1;");
  EXPECT_EQ(d.exit_code, 2) << d.output;
  EXPECT_NE(d.output.find("t.csv: cannot be written: File too large"), std::string::npos) << d.output;
  EXPECT_FALSE(fs::exists(Path("t.csv")));
  EXPECT_EQ(Leftovers(), 0);
}

}  // namespace

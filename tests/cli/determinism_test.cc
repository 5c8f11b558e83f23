// The same inputs give byte-identical outputs whatever the thread count (docs/robustness.md): detection and the
// device calibration run with OpenCV on one thread and on four (OPENCV_FOR_THREADS_NUM; the connected components and
// the undistortion maps are OpenCV's parallel code) and again on four.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/cli_harness.h"

namespace {

namespace fs = std::filesystem;
using topocal::testing_cli::RunTopocal;

class Determinism : public topocal::testing_cli::TempDirTest {
 protected:
  const std::string data_ = std::string(TOPOCAL_SOURCE_DIR) + "/data/";
};

TEST_F(Determinism, DetectIsByteIdenticalWhateverTheThreads) {
  // A clinical-looking capture: lid with skin, an iris, glints (the local-background and deblending paths).
  ASSERT_EQ(RunTopocal("render-spots --config " + paper_ + " --device " + data_ + "device.json --sigma 0 " +
                       "--upper-lid 0.2 --lid-skin 2000 --iris 1500 --glints 3 --seed 4 --out " + Path("eye.png"))
                .exit_code,
            0);
  std::string csv[3], json[3];
  const char* threads[3] = {"1", "4", "4"};
  for (int i = 0; i < 3; ++i) {
    const auto r = RunTopocal("detect --config " + paper_ + " --device " + data_ + "device.json --image " +
                                  Path("eye.png") + " --out " + Path("d.csv") + " --json " + Path("d.json"),
                              std::string("OPENCV_FOR_THREADS_NUM=") + threads[i]);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    csv[i] = Bytes("d.csv");
    json[i] = Bytes("d.json");
  }
  EXPECT_FALSE(csv[0].empty());
  EXPECT_EQ(csv[0], csv[1]);
  EXPECT_EQ(csv[1], csv[2]);
  EXPECT_EQ(json[0], json[1]);
  EXPECT_EQ(json[1], json[2]);
}

TEST_F(Determinism, DeviceCalibrationIsByteIdenticalWhateverTheThreads) {
  std::string balls;
  for (const auto& [r, at] : {std::pair{"6.5", "0.12 -0.20 0.00"}, std::pair{"7.8", "-0.25 0.10 -0.15"},
                              std::pair{"9.0", "0.20 0.22 0.10"}}) {
    const std::string out = Path(std::string("ball-") + r + ".png");
    ASSERT_EQ(RunTopocal("render-spots --config " + paper_ + " --device " + data_ + "demo-unit-device.json " +
                         "--sphere-radius-mm " + r + " --ball-at " + at + " --out " + out)
                  .exit_code,
              0);
    balls += " " + out;
  }
  std::string device[2];
  const char* threads[2] = {"1", "4"};
  for (int i = 0; i < 2; ++i) {
    const auto r = RunTopocal("device calibrate --config " + paper_ + " --device " + data_ + "device.json --balls" +
                                  balls + " --radii-mm 6.5 7.8 9.0 --out " + Path("unit-device.json"),
                              std::string("OPENCV_FOR_THREADS_NUM=") + threads[i]);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    device[i] = Bytes("unit-device.json");
  }
  EXPECT_FALSE(device[0].empty());
  EXPECT_EQ(device[0], device[1]);
}

}  // namespace

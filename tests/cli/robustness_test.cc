// End to end: hostile inputs are bad input (exit 2, one short line naming the file and key), never a crash,
// a wrapped integer or a result computed to Inf. Each test is a reproducer from a mutation campaign.
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "tests/cli_harness.h"

namespace {

namespace fs = std::filesystem;

using topocal::testing_cli::Run;
using topocal::testing_cli::RunTopocal;

class Robustness : public topocal::testing_cli::TempDirTest {
 protected:
  // The paper's configuration with `from` replaced by `to`, written to `name`.
  std::string PaperWith(const std::string& name, const std::string& from, const std::string& to) const {
    std::ifstream in(paper_);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    Write(name, text.replace(at, from.size(), to));
    return Path(name);
  }
};

// One line on stderr (plus nothing else), short, exit 2.
void ExpectBadInput(const Run& r, const std::string& needle) {
  EXPECT_EQ(r.exit_code, 2) << r.output.substr(0, 300);
  EXPECT_NE(r.output.find(needle), std::string::npos) << r.output.substr(0, 300);
  EXPECT_LT(r.output.size(), 400u) << r.output.substr(0, 300);
}

// An empty value (a shell variable never set) was read as 0 for a number: `--sigma ''` simulated sigma = 0. Refused
// before any work, naming the option, for numbers and paths alike.
TEST_F(Robustness, AnEmptyOptionValueIsRefusedNamingTheOption) {
  const auto sigma = RunTopocal("simulate --config " + paper_ + " --sigma '' --out " + Path("s.csv"));
  EXPECT_EQ(sigma.exit_code, 2) << sigma.output;
  EXPECT_NE(sigma.output.find("--sigma: an empty value"), std::string::npos) << sigma.output;
  EXPECT_FALSE(fs::exists(Path("s.csv")));
  const auto config = RunTopocal("design --config ' ' --out " + Path("t.csv"));
  EXPECT_EQ(config.exit_code, 2) << config.output;
  EXPECT_NE(config.output.find("--config: an empty value"), std::string::npos) << config.output;
}

TEST_F(Robustness, ConfigIntegerBeyondIntIsRefusedNotWrapped) {
  const auto cfg = PaperWith("c.json", "\"rings_N\": 11", "\"rings_N\": 4294967297");
  ExpectBadInput(RunTopocal("design --config " + cfg + " --out " + Path("t.csv")), "ideal_image.rings_N: must be in");
  EXPECT_FALSE(fs::exists(Path("t.csv")));
}

TEST_F(Robustness, DeeplyNestedConfigurationsDoNotCrash) {
  Write("deep.json", std::string(100000, '['));
  ExpectBadInput(RunTopocal("design --config " + Path("deep.json") + " --out " + Path("t.csv")), "nested deeper");
  ExpectBadInput(RunTopocal("simulate --config " + paper_ + " --device " + Path("deep.json") + " --out " + Path("s.csv")),
                 "nested deeper");
  ExpectBadInput(RunTopocal("harness --config " + Path("deep.json") + " --out " + Path("h")), "nested deeper");
}

TEST_F(Robustness, BatchInputsWithHostileNumbersAreBadInput) {
  fs::create_directories(dir_ / "line" / "u1");
  fs::create_directories(dir_ / "line" / "u2");
  Write("line/u1/unit-inputs.json",
        R"({"serial": "SN-1", "target": "t.yaml", "images": "v.png", "sphere_radius_mm": 1e999})");
  Write("line/u2/unit-inputs.json",
        R"({"serial": "SN-2", "target": "t.yaml", "images": "v.png", "uncertainty_samples": 4294967297})");
  Write("line/u2/v.png", "");  // the image glob is resolved before the numbers are read
  const auto r = RunTopocal("unit calibrate-batch " + Path("line") + " --out " + Path("units"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("u1/unit-inputs.json: sphere_radius_mm: a number beyond the range of a double"),
            std::string::npos) << r.output;
  EXPECT_NE(r.output.find("u2/unit-inputs.json: uncertainty_samples: must be in [0, 100000]"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(Path("units/SN-1")));
}

TEST_F(Robustness, HarnessConfigHostileNumbersAreBadInput) {
  const std::string good = R"({"design": ")" + paper_ + R"(", "seed": 3, "pixel_pitch_um": 1.12,
      "distortion": {"seidel_sigma_per_mm2": [-1e-6, 6.3e-5]},
      "noise_px": [0.01], "noise_draws": 1, "calibration_errors": [-1, 0, 0.1],
      "limits": {"dk": 0.05, "dP_D": 0.25}})";
  const auto with = [&](const std::string& name, const std::string& from, const std::string& to) {
    std::string text = good;
    text.replace(text.find(from), from.size(), to);
    Write(name, text);
    return Path(name);
  };
  ExpectBadInput(RunTopocal("harness --config " + with("h.json", "\"noise_draws\": 1", "\"noise_draws\": 4294967297") +
                            " --out " + Path("h")),
                 "noise_draws: must lie in");
  ExpectBadInput(RunTopocal("harness --config " + with("h2.json", "1.12", "1e999") + " --out " + Path("h")),
                 "h2.json: pixel_pitch_um: a number beyond the range of a double");
  ExpectBadInput(RunTopocal("harness --config " + with("h3.json", "\"seed\": 3,", "\"seed\": 3, \"seed\": 4,") +
                            " --out " + Path("h")),
                 "h3.json: seed: given twice in one object");
  ExpectBadInput(RunTopocal("harness --config " + Path("h3.json") + " --out " + Path("h") + " --jobs 100000"), "--jobs");
  EXPECT_FALSE(fs::exists(Path("h")));
}

TEST_F(Robustness, SigmaThatFoldsTheImageIsRefused) {
  // --sigma 1e308 wrote 624 rows of -inf with exit 0.
  ExpectBadInput(RunTopocal("simulate --config " + paper_ + " --sigma 1e308 --out " + Path("s.csv")),
                 "--sigma 1e+308: folds the image");
  EXPECT_FALSE(fs::exists(Path("s.csv")));
  ExpectBadInput(RunTopocal("simulate --config " + paper_ + " --sigma -1e-2 --out " + Path("s.csv")), "folds the image");
  ASSERT_EQ(RunTopocal("simulate --config " + paper_ + " --sigma -2e-4 --out " + Path("s.csv")).exit_code, 0);
  const auto cfg = PaperWith("c.json", "2.0e-4]", "2.0e-2]");
  ExpectBadInput(RunTopocal("design --config " + cfg + " --out " + Path("t.csv")), "distortion.sigmas_per_mm2[6]");
}

TEST_F(Robustness, TargetLengthsAreCheckedAfterTheConversionToMm) {
  // colSpacingMeters 1e308 passed the check in metres and wrote an SVG width="infmm".
  Write("t.yaml", "target_type: checkerboard\ntargetCols: 6\ntargetRows: 5\nrowSpacingMeters: 0.01\n"
                  "colSpacingMeters: 1e308\n");
  ExpectBadInput(RunTopocal("target --target " + Path("t.yaml") + " --out " + Path("t.svg")),
                 "t.yaml: colSpacingMeters: must be at most 10 m");
  EXPECT_FALSE(fs::exists(Path("t.svg")));
  // targetCols: 4294967298 was read by OpenCV's (int)strtol as 2.
  Write("w.yaml", "target_type: checkerboard\ntargetCols: 4294967298\ntargetRows: 5\nrowSpacingMeters: 0.01\n"
                  "colSpacingMeters: 0.01\n");
  ExpectBadInput(RunTopocal("target --target " + Path("w.yaml") + " --out " + Path("t.svg")),
                 "w.yaml: line 2: 4294967298: an integer beyond the range of int");
}

// A key given twice: OpenCV keeps both and reads the first, so the second value (a later edit) was silently ignored.
TEST_F(Robustness, AYamlKeyGivenTwiceIsRefused) {
  Write("twice.yaml", "target_type: checkerboard\ntargetCols: 6\ntargetRows: 5\nrowSpacingMeters: 0.01\n"
                      "colSpacingMeters: 0.01\ntargetCols: 8\n");
  ExpectBadInput(RunTopocal("target --target " + Path("twice.yaml") + " --out " + Path("t.svg")),
                 "twice.yaml: targetCols: the key appears twice");
  EXPECT_FALSE(fs::exists(Path("t.svg")));
}

TEST_F(Robustness, DeeplyNestedYamlDoesNotCrashOpenCv) {
  // cv::FileStorage's parsers recurse: 1e5 nested '[' overflowed the stack (SIGSEGV).
  Write("deep.yaml", "target_type: " + std::string(100000, '[') + "\n");
  ExpectBadInput(RunTopocal("target --target " + Path("deep.yaml") + " --out " + Path("t.svg")),
                 "deep.yaml: nested deeper than 64 levels");
  Write("deep-cal.yaml", "%YAML:1.0\n---\ncamera_matrix:\n" + std::string(2000, ' ') + [] {
    std::string dashes;
    for (int i = 0; i < 100000; ++i) dashes += "- ";
    return dashes;
  }() + "1\n");
  ExpectBadInput(RunTopocal("undistort --calibration " + Path("deep-cal.yaml") + " --spots " + Path("none.csv") +
                            " --out " + Path("o.csv")),
                 "deep-cal.yaml: nested deeper than 64 levels");
  Write("deep.xml", "<?xml version=\"1.0\"?>\n<opencv_storage>" + std::string(100000, '<') + "</opencv_storage>\n");
  ExpectBadInput(RunTopocal("undistort --calibration " + Path("deep.xml") + " --spots " + Path("none.csv") +
                            " --out " + Path("o.csv")),
                 "deep.xml: nested deeper than 64 levels");
}

// Found by libFuzzer: OpenCV 4.6's YAML parser loops forever on a non-ASCII byte where a key should start. Such a
// byte outside a quoted string or comment is refused before the parser sees it; quoted and in comments it is fine.
TEST_F(Robustness, YamlThatHangsOpenCvsParserNeverReachesIt) {
  Write("hang.yaml", "%YAML:1.0\n s: 5\n\xd2 -\nx");
  ExpectBadInput(RunTopocal("undistort --calibration " + Path("hang.yaml") + " --spots " + Path("none.csv") +
                            " --out " + Path("o.csv")),
                 "hang.yaml: line 3: a non-ASCII byte outside a quoted string or comment");
  // ... and on a line that is no key nor list item, or left of the first key (" s:5" then "-- -").
  Write("dashes.yaml", "%YAML:1.0\n s:5\n-- -\n ");
  ExpectBadInput(RunTopocal("undistort --calibration " + Path("dashes.yaml") + " --spots " + Path("none.csv") +
                            " --out " + Path("o.csv")),
                 "dashes.yaml: line 2: not a line of a YAML mapping");
  Write("quoted.yaml", "# r\xc3\xa9glage\ntarget_type: \"checkerboard\"\ntargetCols: 4\ntargetRows: 3\n"
                       "rowSpacingMeters: 0.01\ncolSpacingMeters: 0.01\nnote: \"caf\xc3\xa9\"\n");
  const auto quoted = RunTopocal("target --target " + Path("quoted.yaml") + " --out " + Path("t.svg"));
  EXPECT_EQ(quoted.output.find("non-ASCII"), std::string::npos) << quoted.output;
}

TEST_F(Robustness, ATwoRowCameraMatrixIsBadInput) {
  // Data for 3 x 3 under rows: 2 — an OpenCV assertion, once exit 1 with OpenCV's text.
  const std::string cal =
      "%YAML:1.0\n---\nimage_width: 320\nimage_height: 240\n"
      "camera_matrix: !!opencv-matrix\n   rows: 2\n   cols: 3\n   dt: d\n"
      "   data: [ 300., 0., 160., 0., 300., 120., 0., 0., 1. ]\n"
      "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n"
      "   data: [ -0.1, 0.01, 0., 0., 0. ]\n";
  Write("cal.yaml", cal);
  Write("board.yaml", "target_type: checkerboard\ntargetCols: 6\ntargetRows: 5\nrowSpacingMeters: 0.01\n"
                      "colSpacingMeters: 0.01\n");
  ExpectBadInput(RunTopocal("render-target --target " + Path("board.yaml") + " --camera " + Path("cal.yaml") +
                            " --out " + Path("v.png") + " --distance-mm 600"),
                 "cal.yaml: camera_matrix: expected 3x3, found 2x3");
  ExpectBadInput(RunTopocal("undistort --calibration " + Path("cal.yaml") + " --spots " + Path("none.csv") + " --out " +
                            Path("o.csv")),
                 "cal.yaml: camera_matrix: expected 3x3, found 2x3");
  // A declared size of 1e5 x 1e5 whose data do not match: bad input, whichever check sees it first.
  std::string huge = cal;
  huge.replace(huge.find("rows: 2\n   cols: 3"), 19, "rows: 100000\n   cols: 100000");
  Write("huge.yaml", huge);
  ExpectBadInput(RunTopocal("undistort --calibration " + Path("huge.yaml") + " --spots " + Path("none.csv") +
                            " --out " + Path("o.csv")),
                 "huge.yaml: ");
}

TEST_F(Robustness, AnInfiniteFocalLengthNeverReachesCeres) {
  Write("board.yaml", "target_type: checkerboard\ntargetCols: 6\ntargetRows: 5\nrowSpacingMeters: 0.01\n"
                      "colSpacingMeters: 0.01\n");
  Write("view.png", "");
  for (const char* focal : {"inf", "1e308"}) {
    const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images " + Path("view.png") +
                              " --model seidel --single-view --focal-mm " + focal +
                              " --pixel-pitch-um 1e-300 --distance-mm 70 --out " + Path("cal.yaml"));
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find("focal"), std::string::npos) << r.output;
  }
  EXPECT_FALSE(fs::exists(Path("cal.yaml")));
}

}  // namespace

// The image codecs are a plugin loaded at the first image (imageio/image_file.h): without it, a verb that writes or
// reads an image fails with one line naming the file (exit 1: a broken installation, not bad input) and writes
// nothing, while the verbs that touch no image run as before.
TEST_F(Robustness, AMissingCodecsPluginIsOneLineNamingItAndOnlyImageVerbsNeedIt) {
  const auto run_with_plugin = [&](const std::string& plugin, const std::string& args) {
    return RunTopocal(args, "TOPOCAL_IMGCODECS_PLUGIN=" + plugin);
  };
  const std::string render = "render-spots --config " + paper_ + " --device " + TOPOCAL_SOURCE_DIR +
                             "/data/device.json --sigma 6.3e-5 --out " + Path("s.png");
  const topocal::testing_cli::Run missing = run_with_plugin(Path("nowhere/libtopocal_imgcodecs.so"), render);
  EXPECT_EQ(missing.exit_code, 1) << missing.output;
  EXPECT_NE(missing.output.find("libtopocal_imgcodecs.so is not installed: not found at " +
                                Path("nowhere/libtopocal_imgcodecs.so")),
            std::string::npos)
      << missing.output;
  EXPECT_EQ(std::count(missing.output.begin(), missing.output.end(), '\n'), 1) << missing.output;
  EXPECT_FALSE(fs::exists(Path("s.png")));

  Write("not-a-plugin.so", "not a shared object\n");
  const topocal::testing_cli::Run bogus = run_with_plugin(Path("not-a-plugin.so"), render);
  EXPECT_EQ(bogus.exit_code, 1) << bogus.output;
  EXPECT_NE(bogus.output.find(Path("not-a-plugin.so") + ": cannot load the image codecs plugin"), std::string::npos)
      << bogus.output;
  EXPECT_EQ(std::count(bogus.output.begin(), bogus.output.end(), '\n'), 1) << bogus.output;
  EXPECT_FALSE(fs::exists(Path("s.png")));

  const topocal::testing_cli::Run sweep = run_with_plugin(Path("nowhere/libtopocal_imgcodecs.so"), "sweep --config " + paper_);
  EXPECT_EQ(sweep.exit_code, 0) << sweep.output.substr(0, 300);
}

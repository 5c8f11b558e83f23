// The readers of other tools' calibrations (calib/camera_import.cc): what topocal exports to mrcal and ROS comes
// back as the same camera; files in the form mrcal and PyYAML write them are read; malformed and non-physical files
// are refused with one line naming the file and the key. (That mrcal and PyYAML themselves write files these
// readers take is tests/exchange/exchange_test.py.)
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "calib/camera_exchange.h"
#include "calib/distortion_valid_region.h"
#include "util/io.h"

namespace topocal::calib {
namespace {

namespace fs = std::filesystem;

// A camera whose every number has 16-17 significant digits and differs from the others, so that a lost digit or a
// swapped coefficient shows.
model::CameraModel Camera() {
  model::CameraModel c;
  c.width_px = 1600;
  c.height_px = 1200;
  c.fx_px = 1510.2513417782913;
  c.fy_px = 1508.7490331246317;
  c.cx_px = 801.53371928117363;
  c.cy_px = 597.24880317294022;
  c.dist = {-0.23101894317712531, 0.091734109917362014, 0.0011317781220496312, -0.00071092741155812219,
            -0.019537782177182635};
  return c;
}

// Text as exports go through it: 17 significant digits read back correctly rounded.
constexpr double kRoundTrip = 1e-12;

void ExpectSameCamera(const model::CameraModel& got, const model::CameraModel& want, double rel) {
  EXPECT_EQ(got.width_px, want.width_px);
  EXPECT_EQ(got.height_px, want.height_px);
  const auto near = [rel](double a, double b) { return std::abs(a - b) <= rel * std::max(1.0, std::abs(b)); };
  EXPECT_PRED2(near, got.fx_px, want.fx_px);
  EXPECT_PRED2(near, got.fy_px, want.fy_px);
  EXPECT_PRED2(near, got.cx_px, want.cx_px);
  EXPECT_PRED2(near, got.cy_px, want.cy_px);
  for (size_t i = 0; i < 5; ++i) EXPECT_PRED2(near, got.dist[i], want.dist[i]) << "coefficient " << i;
  EXPECT_TRUE(got.distortion_centre.isZero(0));
}

class CameraImportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("topocal_camimport_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& name, const std::string& text) const {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }
  // `text` with `from` replaced by `to`; a `from` that is not there fails the test (the case would test nothing).
  static std::string Replaced(std::string text, const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    if (at == std::string::npos) {
      ADD_FAILURE() << "'" << from << "' not in the base text";
      return text;
    }
    return text.replace(at, from.size(), to);
  }
  // Reading `text` (written to `name`) with `read` is refused in one line that starts with the file and names the
  // key and the problem.
  template <typename Read>
  void ExpectRefused(Read read, const std::string& name, const std::string& text, const std::string& key,
                     const std::string& problem) {
    const std::string path = Write(name, text);
    try {
      const model::CameraModel c = read(path);
      ADD_FAILURE() << name << ": accepted (fx " << c.fx_px << "), expected a refusal naming " << key;
    } catch (const util::InputError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << what;
      EXPECT_NE(what.find(key), std::string::npos) << "key '" << key << "' not named: " << what;
      EXPECT_NE(what.find(problem), std::string::npos) << "problem '" << problem << "' not said: " << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << "not one line: " << what;
    }
  }
  fs::path dir_;
};

// ---- round trips ---------------------------------------------------------------------------------------------------

TEST_F(CameraImportTest, MrcalExportThenImportIsTheIdentity) {
  const model::CameraModel c = Camera();
  ExpectSameCamera(ReadMrcalCameraModel(Write("cam.cameramodel", MrcalCameraModelText(c))), c, kRoundTrip);
  // With the valid region's contour (nested lists the reader reads over).
  const DistortionValidRegion region{700.0, false};
  const std::string with_region = MrcalCameraModelText(c, &region);
  ASSERT_NE(with_region.find("valid_intrinsics_region"), std::string::npos);
  ExpectSameCamera(ReadMrcalCameraModel(Write("region.cameramodel", with_region)), c, kRoundTrip);
}

TEST_F(CameraImportTest, RosExportThenImportIsTheIdentity) {
  const model::CameraModel c = Camera();
  ExpectSameCamera(ReadRosCameraInfo(Write("camera_info.yaml", RosCameraInfoYaml(c, "topo_cam"))), c, kRoundTrip);
}

// ---- mrcal ---------------------------------------------------------------------------------------------------------

// What mrcal.cameramodel.write produces (mrcal 2.x, cameramodel.py _write): comments, 10 significant digits, trailing
// commas everywhere, the valid region closed by "]," at column 0, and a solve's optimization_inputs as a bytes literal.
const char kMrcalWritten[] = R"(# generated on 2026-12-03 with   mrcal-calibrate-cameras --corners-cache corners.vnl
{
    'lensmodel':  'LENSMODEL_OPENCV5',

    # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....
    'intrinsics': [ 1510.25, 1508.75, 801.5, 597.25, -0.231, 0.0917, 0.00113, -0.00071, -0.0195,],

    'valid_intrinsics_region': [
    [ 10, 20 ],
    [ 1500, 20 ],
    [ 1500, 1100 ],
    [ 10, 20 ],
],

    # extrinsics are rt_fromref
    'extrinsics': [ 0.001, -0.002, 0.003, 0.1, 0.2, 0.3,],

    'imagersize': [ 1600, 1200,],

    'icam_intrinsics': 0,

    # The optimization inputs contain all the data used to compute this model.
    'optimization_inputs': b'P)h>@6aWAK2mk;8Axs%Z3qxlN003$P000pH!t"#\'}',

}
)";

TEST_F(CameraImportTest, MrcalReadsTheFileAsMrcalWritesIt) {
  const model::CameraModel c = ReadMrcalCameraModel(Write("mrcal.cameramodel", kMrcalWritten));
  model::CameraModel want;
  want.width_px = 1600;
  want.height_px = 1200;
  want.fx_px = 1510.25;
  want.fy_px = 1508.75;
  want.cx_px = 801.5;
  want.cy_px = 597.25;
  want.dist = {-0.231, 0.0917, 0.00113, -0.00071, -0.0195};
  ExpectSameCamera(c, want, 0);  // decimal text to the nearest double: exact
}

TEST_F(CameraImportTest, MrcalLensModelsTopocalHoldsAreRead) {
  const std::string base = kMrcalWritten;
  // OPENCV4: k3 = 0. Double quotes and a tuple are Python literals too.
  const model::CameraModel four = ReadMrcalCameraModel(Write(
      "four.cameramodel", Replaced(Replaced(base, "'LENSMODEL_OPENCV5'", "\"LENSMODEL_OPENCV4\""),
                                   "[ 1510.25, 1508.75, 801.5, 597.25, -0.231, 0.0917, 0.00113, -0.00071, -0.0195,]",
                                   "(1510.25, 1508.75, 801.5, 597.25, -0.231, 0.0917, 0.00113, -0.00071)")));
  EXPECT_EQ(four.dist[3], -0.00071);
  EXPECT_EQ(four.dist[4], 0.0);
  // OPENCV8 with k4 = k5 = k6 = 0: the five coefficients.
  const model::CameraModel eight = ReadMrcalCameraModel(Write(
      "eight.cameramodel",
      Replaced(Replaced(base, "'LENSMODEL_OPENCV5'", "'LENSMODEL_OPENCV8'"), "-0.0195,]", "-0.0195, 0, 0.0, -0.0]")));
  EXPECT_EQ(eight.dist[4], -0.0195);
  EXPECT_EQ(eight.fx_px, 1510.25);
  // PINHOLE: no distortion.
  const model::CameraModel pinhole = ReadMrcalCameraModel(
      Write("pinhole.cameramodel", Replaced(Replaced(base, "'LENSMODEL_OPENCV5'", "'LENSMODEL_PINHOLE'"),
                                            ", -0.231, 0.0917, 0.00113, -0.00071, -0.0195,]", "]")));
  EXPECT_EQ(pinhole.cy_px, 597.25);
  for (const double d : pinhole.dist) EXPECT_EQ(d, 0.0);
}

TEST_F(CameraImportTest, MrcalModelsTopocalCannotHoldAreRefusedNamingTheModel) {
  const std::string base = kMrcalWritten;
  const auto read = [](const std::string& p) { return ReadMrcalCameraModel(p); };
  ExpectRefused(
      read, "splined.cameramodel",
      Replaced(base, "LENSMODEL_OPENCV5", "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=12_fov_x_deg=100"),
      "lensmodel", "'LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=12_fov_x_deg=100' is not a model topocal holds");
  ExpectRefused(read, "cahvor.cameramodel", Replaced(base, "LENSMODEL_OPENCV5", "LENSMODEL_CAHVOR"), "lensmodel",
                "'LENSMODEL_CAHVOR'");
  ExpectRefused(read, "opencv12.cameramodel", Replaced(base, "LENSMODEL_OPENCV5", "LENSMODEL_OPENCV12"), "lensmodel",
                "'LENSMODEL_OPENCV12'");
}

TEST_F(CameraImportTest, MrcalMalformedOrNonPhysicalFilesAreRefusedNamingTheKey) {
  const std::string base = kMrcalWritten;
  const std::string in = "[ 1510.25, 1508.75, 801.5, 597.25, -0.231, 0.0917, 0.00113, -0.00071, -0.0195,]";
  const auto read = [](const std::string& p) { return ReadMrcalCameraModel(p); };
  ExpectRefused(read, "no-intrinsics.cameramodel", Replaced(base, "'intrinsics': " + in + ",", ""), "intrinsics",
                "missing");
  ExpectRefused(read, "no-size.cameramodel", Replaced(base, "'imagersize': [ 1600, 1200,],", ""), "imagersize",
                "missing");
  ExpectRefused(read, "no-lens.cameramodel", Replaced(base, "'lensmodel':  'LENSMODEL_OPENCV5',", ""), "lensmodel",
                "missing");
  ExpectRefused(read, "short.cameramodel", Replaced(base, "-0.00071, -0.0195,]", "-0.00071,]"), "intrinsics",
                "LENSMODEL_OPENCV5 has 9 numbers");
  ExpectRefused(read, "text.cameramodel", Replaced(base, "1508.75,", "'1508.75',"), "intrinsics",
                "not a list of numbers");
  ExpectRefused(read, "fx0.cameramodel", Replaced(base, "[ 1510.25,", "[ 0.0,"), "intrinsics", "must be > 0");
  ExpectRefused(read, "fy-.cameramodel", Replaced(base, "1508.75,", "-1508.75,"), "intrinsics", "must be > 0");
  ExpectRefused(read, "cx.cameramodel", Replaced(base, "801.5,", "1600.5,"), "intrinsics",
                "principal point (1600.5, 597.25) px lies outside the 1600 x 1200 image");
  ExpectRefused(read, "cy.cameramodel", Replaced(base, "597.25,", "-3,"), "intrinsics", "principal point");
  ExpectRefused(read, "nan.cameramodel", Replaced(base, "0.0917,", "nan,"), "intrinsics",
                "'nan' is not a Python literal");
  ExpectRefused(read, "inf.cameramodel", Replaced(base, "0.0917,", "-inf,"), "intrinsics",
                "'-inf' is not a decimal number");
  ExpectRefused(read, "huge.cameramodel", Replaced(base, "0.0917,", "1e999,"), "intrinsics",
                "beyond the range of a double");
  ExpectRefused(read, "hex.cameramodel", Replaced(base, "0.0917,", "0x10,"), "intrinsics", "not a decimal number");
  ExpectRefused(read, "width0.cameramodel", Replaced(base, "[ 1600, 1200,]", "[ 0, 1200,]"), "imagersize",
                "two positive integers");
  ExpectRefused(read, "width-float.cameramodel", Replaced(base, "[ 1600, 1200,]", "[ 1600.5, 1200,]"), "imagersize",
                "two positive integers");
  ExpectRefused(read, "size3.cameramodel", Replaced(base, "[ 1600, 1200,]", "[ 1600, 1200, 3]"), "imagersize",
                "two positive integers");
  ExpectRefused(read, "twice.cameramodel", Replaced(base, "'imagersize': [ 1600, 1200,],", "'intrinsics': " + in + ","),
                "intrinsics", "the key appears twice");
  ExpectRefused(read, "open-string.cameramodel", Replaced(base, "'LENSMODEL_OPENCV5',", "'LENSMODEL_OPENCV5,"),
                "lensmodel", "line 3: a string is not closed on its line");
  ExpectRefused(read, "no-comma.cameramodel", Replaced(base, "0.0917,", "0.0917"), "intrinsics", "expected ',' or ']'");
  const auto last_line = std::count(base.begin(), base.end(), '\n') + 1;
  ExpectRefused(read, "after.cameramodel", base + "{}\n", "line " + std::to_string(last_line),
                "'{}\\x0a' after the dict's closing '}'");
  ExpectRefused(read, "deep.cameramodel",
                Replaced(base, "'icam_intrinsics': 0", "'icam_intrinsics': " + std::string(100000, '[')),
                "icam_intrinsics", "nested deeper than 64 levels");
  ExpectRefused(read, "yaml.cameramodel", "lensmodel: LENSMODEL_OPENCV5\n", "line 1", "not a Python dict");
  ExpectRefused(read, "empty.cameramodel", " \n# nothing\n", "line 3", "empty");
  ExpectRefused(read, "list.cameramodel", "{'lensmodel': 'LENSMODEL_OPENCV5', 'intrinsics': 5}", "intrinsics",
                "not a list of numbers");
  const std::string missing = (dir_ / "missing.cameramodel").string();
  try {
    ReadMrcalCameraModel(missing);
    ADD_FAILURE() << "a missing file was read";
  } catch (const util::InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(missing + ": ", 0), 0u) << e.what();
  }
}

// ---- ROS camera_info ---------------------------------------------------------------------------------------------

// yaml.safe_dump of a camera_info dict (PyYAML 6): keys sorted, block sequences at their key's indentation.
const char kPyYamlWritten[] = R"(camera_matrix:
  cols: 3
  data:
  - 1510.25
  - 0.0
  - 801.5
  - 0.0
  - 1508.75
  - 597.25
  - 0.0
  - 0.0
  - 1.0
  rows: 3
camera_name: narrow_stereo
distortion_coefficients:
  cols: 5
  data:
  - -0.231
  - 0.0917
  - 0.00113
  - -0.00071
  - -0.0195
  rows: 1
distortion_model: plumb_bob
image_height: 1200
image_width: 1600
projection_matrix:
  cols: 4
  data: [1400.0, 0.0, 790.0, 0.0, 0.0, 1400.0, 600.0, 0.0, 0.0, 0.0, 1.0, 0.0]
  rows: 3
rectification_matrix:
  cols: 3
  data: [0.999, 0.01, 0.0, -0.01, 0.999, 0.0, 0.0, 0.0, 1.0]
  rows: 3
)";

TEST_F(CameraImportTest, RosReadsTheFileAsPyYamlWritesIt) {
  const model::CameraModel c = ReadRosCameraInfo(Write("pyyaml.yaml", kPyYamlWritten));
  model::CameraModel want;
  want.width_px = 1600;
  want.height_px = 1200;
  want.fx_px = 1510.25;
  want.fy_px = 1508.75;
  want.cx_px = 801.5;
  want.cy_px = 597.25;
  want.dist = {-0.231, 0.0917, 0.00113, -0.00071, -0.0195};
  ExpectSameCamera(c, want, 0);  // K and D, not the rectified P
  // rational_polynomial with k4..k6 = 0 is the same camera.
  const std::string rational =
      Replaced(Replaced(Replaced(kPyYamlWritten, "plumb_bob", "rational_polynomial"), "  cols: 5", "  cols: 8"),
               "  - -0.0195\n", "  - -0.0195\n  - 0.0\n  - 0.0\n  - 0.0\n");
  ExpectSameCamera(ReadRosCameraInfo(Write("rational.yaml", rational)), want, 0);
}

TEST_F(CameraImportTest, RosMalformedOrNonPhysicalFilesAreRefusedNamingTheKey) {
  const std::string base = RosCameraInfoYaml(Camera(), "cam");
  const std::string py = kPyYamlWritten;
  const auto read = [](const std::string& p) { return ReadRosCameraInfo(p); };
  ExpectRefused(read, "fisheye.yaml", Replaced(base, "plumb_bob", "equidistant"), "distortion_model", "'equidistant'");
  ExpectRefused(read, "four.yaml", Replaced(py, "  - -0.0195\n", ""), "distortion_coefficients.data",
                "plumb_bob has 5 coefficients, found 4");
  ExpectRefused(read, "cols.yaml", Replaced(py, "  cols: 5", "  cols: 4"), "distortion_coefficients",
                "expected 1 x 5, found rows 1, cols 4");
  ExpectRefused(read, "k-cols.yaml", Replaced(py, "  cols: 3", "  cols: 4"), "camera_matrix", "expected 3 x 3");
  ExpectRefused(read, "k-short.yaml", Replaced(py, "  - 1.0\n", ""), "camera_matrix.data",
                "expected a list of 9 numbers");
  ExpectRefused(read, "skew.yaml", Replaced(py, "  - 801.5\n  - 0.0\n", "  - 801.5\n  - 0.5\n"), "camera_matrix",
                "not a pinhole camera matrix");
  ExpectRefused(read, "fx0.yaml", Replaced(py, "  - 1510.25\n", "  - 0.0\n"), "camera_matrix", "must be > 0");
  ExpectRefused(read, "cx.yaml", Replaced(py, "  - 801.5\n", "  - -0.75\n"), "camera_matrix",
                "principal point (-0.75, 597.25) px lies outside the 1600 x 1200 image");
  ExpectRefused(read, "cy.yaml", Replaced(py, "  - 597.25\n", "  - 1199.75\n"), "camera_matrix", "principal point");
  ExpectRefused(read, "nan.yaml", Replaced(py, "  - 0.0917\n", "  - .nan\n"), "distortion_coefficients.data",
                "non-finite value");
  ExpectRefused(read, "inf.yaml", Replaced(py, "  - 1508.75\n", "  - .inf\n"), "camera_matrix.data",
                "non-finite value");
  ExpectRefused(read, "huge.yaml", Replaced(py, "  - 1508.75\n", "  - -1e999\n"), "camera_matrix.data",
                "non-finite value");
  ExpectRefused(read, "word.yaml", Replaced(py, "  - 0.0917\n", "  - nan\n"), "distortion_coefficients.data",
                "not a number");
  ExpectRefused(read, "width0.yaml", Replaced(py, "image_width: 1600", "image_width: 0"), "image_width", "must be > 0");
  ExpectRefused(read, "width-real.yaml", Replaced(py, "image_width: 1600", "image_width: 1600.5"), "image_width",
                "not an integer");
  ExpectRefused(read, "no-height.yaml", Replaced(py, "image_height: 1200\n", ""), "image_height", "missing");
  ExpectRefused(read, "no-model.yaml", Replaced(py, "distortion_model: plumb_bob\n", ""), "distortion_model",
                "missing");
  ExpectRefused(read, "no-k.yaml", Replaced(base, "camera_matrix:", "camera_matrixx:"), "camera_matrix", "missing");
  ExpectRefused(read, "twice.yaml", py + "image_width: 800\n", "image_width", "the key appears twice");
  ExpectRefused(read, "empty.yaml", "\n\n", "file", "empty");
}

TEST_F(CameraImportTest, KalibrMessagesNameTheCamerasKey) {
  const std::string text = KalibrCamchainYaml(Camera(), "/cam0/image_raw");
  const auto read = [](const std::string& p) { return ReadKalibrCamchain(p); };
  ExpectRefused(read, "camchain.yaml", Replaced(text, "  intrinsics:", "  intrinsicz:"), "cam0.intrinsics", "missing");
}

}  // namespace
// A camera every reader accepts on its own but that no other verb could use (k1 = 1e308: no region where the
// distortion is invertible) is refused by import, naming the file, instead of being written (it was written, exit 0,
// and every verb then refused the result).
TEST_F(CameraImportTest, AnImportedCameraOtherVerbsWouldRefuseIsNotWritten) {
  const std::string path = Write("camchain.yaml",
                                 "cam0:\n  camera_model: pinhole\n  intrinsics: [500.0, 500.0, 320.0, 240.0]\n"
                                 "  distortion_model: radtan\n  distortion_coeffs: [1e308, 0.0, 0.0, 0.0]\n"
                                 "  resolution: [640, 480]\n");
  try {
    (void)ImportCalibrationText("kalibr", path);
    ADD_FAILURE() << "accepted";
  } catch (const util::InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << what;
    EXPECT_NE(what.find("nothing written"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  // The same camera with an ordinary k1 imports.
  const std::string fine = Write("fine.yaml", Replaced(util::ReadFile(path), "1e308", "-0.2"));
  EXPECT_NO_THROW((void)ImportCalibrationText("kalibr", fine));
}

TEST_F(CameraImportTest, MrcalAndRosRationalModelsAreTheRationalLensModel) {
  const model::CameraModel mrcal = ReadMrcalCameraModel(Write(
      "rational.cameramodel", Replaced(Replaced(kMrcalWritten, "'LENSMODEL_OPENCV5'", "'LENSMODEL_OPENCV8'"),
                                       "-0.0195,]", "-0.0195, 0, 0.004, 0]")));
  EXPECT_TRUE(std::holds_alternative<model::RationalPolynomial>(mrcal.lens));
  EXPECT_EQ(mrcal.dist[4], -0.0195);
  EXPECT_EQ(mrcal.dist[6], 0.004);
  const std::string ros =
      Replaced(Replaced(Replaced(kPyYamlWritten, "plumb_bob", "rational_polynomial"), "  cols: 5", "  cols: 8"),
               "  - -0.0195\n", "  - -0.0195\n  - 0.0\n  - 0.25\n  - 0.0\n");
  const model::CameraModel from_ros = ReadRosCameraInfo(Write("rational-k5.yaml", ros));
  EXPECT_TRUE(std::holds_alternative<model::RationalPolynomial>(from_ros.lens));
  EXPECT_EQ(from_ros.dist[6], 0.25);
  // Out and back through each format: the same eight numbers and the same model.
  const model::CameraModel via_ros = ReadRosCameraInfo(Write("out.yaml", RosCameraInfoYaml(from_ros, "cam")));
  EXPECT_TRUE(std::holds_alternative<model::RationalPolynomial>(via_ros.lens));
  EXPECT_EQ(via_ros.dist, from_ros.dist);
  const model::CameraModel via_mrcal =
      ReadMrcalCameraModel(Write("out.cameramodel", MrcalCameraModelText(mrcal, nullptr)));
  EXPECT_TRUE(std::holds_alternative<model::RationalPolynomial>(via_mrcal.lens));
  EXPECT_EQ(via_mrcal.dist, mrcal.dist);
}

}  // namespace topocal::calib

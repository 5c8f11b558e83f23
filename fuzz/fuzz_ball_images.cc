// Fuzz target: a set of reference-ball images as `topocal device calibrate` takes it (pipeline/device_calibration.h):
// the certified radii, duplicates, images that do not index, balls imaged elsewhere than their radius says, lids,
// dropped spots and glints, and image files that are not images — through detection, indexing and the device fit,
// ending in the device file the command would write.
//
// Structure-aware, because a byte-level mutation of a camera-sized PNG almost never decodes to a ball: the input is
// parts separated by "\n--ball--\n", each one ball:
//   line 1:  CERTIFIED_R_MM X_MM Y_MM Z_MM UPPER_LID DROP GLINTS SEED   (missing or unreadable numbers are 0)
//   then, after the first '\n', optionally the bytes of an image file (decoded as the CLI decodes one); without
//   them the ball is rendered in-process (correct::RenderSpotImage) with radius CERTIFIED_R clamped to a ball's,
//   its vertex at (X, Y, Z) clamped to +-1.5 mm, those lids, drop fraction and glints.
// The device is the unit test's tilted-cone device with a 1120 x 1120 camera (10x cheaper to detect than a phone's
// 4000 x 3000); the CLI requires every image to be the device camera's size (imageio::RequireSize), and so does this.
//
// Accepted ends: util::InputError (bad input), std::runtime_error
// from the indexer ("could not be indexed": exit 1, one line), a fit that fails (fit.ok = false). Anything else — a
// crash, a sanitizer report, another exception, a non-finite number in the device file written — is a defect.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "correct/spot_render.h"
#include "correct/spot_truth.h"
#include "fuzz/fuzz_input.h"
#include "imageio/image_file.h"
#include "model/config.h"
#include "model/device.h"
#include "pipeline/device_calibration.h"
#include "util/io.h"
#include "util/json_section.h"

namespace {

using namespace topocal;

constexpr const char* kSeparator = "\n--ball--\n";
constexpr size_t kMaxBalls = 6;

const model::Config& Config() {
  static const model::Config cfg = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  return cfg;
}

const model::Device& Nominal() {
  static const model::Device device = model::ParseDevice(R"({"format": "topocal-device", "format_version": 1,
    "camera": {"pixel_pitch_um": 1.12, "width_px": 1120, "height_px": 1120, "principal_point_px": [559.5, 559.5],
               "a_mm": 5.2},
    "distortion": {"model": "seidel", "sigma_per_mm2": 6.3e-5},
    "screen_pose": {"rx_deg": 0.8, "ry_deg": -0.5, "rz_deg": 0.3, "tx_mm": 0.1, "ty_mm": -0.05, "tz_mm": 0.3}})",
                                                              "fuzz-device.json")
                                              .device;
  return device;
}

struct BallLine {
  double radius_mm = 0, x_mm = 0, y_mm = 0, z_mm = 0, upper_lid = 0, drop = 0;
  int glints = 0;
  unsigned seed = 0;
};

BallLine ParseLine(const std::string& line) {
  double v[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  const char* p = line.c_str();
  for (double& x : v) {
    char* end = nullptr;
    x = std::strtod(p, &end);
    if (end == p) break;
    p = end;
  }
  const auto finite = [](double x) { return std::isfinite(x) ? x : 0.0; };
  BallLine b;
  b.radius_mm = v[0];  // as given: the certified radius the calibration is told
  b.x_mm = std::clamp(finite(v[1]), -1.5, 1.5);
  b.y_mm = std::clamp(finite(v[2]), -1.5, 1.5);
  b.z_mm = std::clamp(finite(v[3]), -1.5, 1.5);
  b.upper_lid = std::clamp(finite(v[4]), 0.0, 0.9);
  b.drop = std::clamp(finite(v[5]), 0.0, 0.9);
  b.glints = static_cast<int>(std::clamp(finite(v[6]), 0.0, 20.0));
  b.seed = static_cast<unsigned>(std::clamp(finite(v[7]), 0.0, 1e6));
  return b;
}

// The rendered image of a ball line (the render-spots path), cached: mutations repeat lines often.
cv::Mat Render(const std::string& line, const BallLine& b) {
  static std::map<std::string, cv::Mat> cache;
  if (auto it = cache.find(line); it != cache.end()) return it->second;
  model::Sphere ball;
  ball.radius_mm = std::clamp(std::isfinite(b.radius_mm) ? b.radius_mm : 7.8, pipeline::kMinBallRadiusMm,
                              pipeline::kMaxBallRadiusMm);
  ball.x0_mm = b.x_mm;
  ball.y0_mm = b.y_mm;
  ball.z0_mm = b.z_mm;
  const auto& device = Nominal();
  const auto truth = correct::SpotsOnSensor(ball, Config().ideal_image, Config().topographer, device);
  correct::SpotRenderOptions o;
  o.seed = b.seed;
  o.lids = correct::LidsOver(truth.spots, b.upper_lid, 0.0);
  auto spots = correct::DropAndAddGlints(truth.spots, b.drop, b.glints, 20.0, b.seed + 1);
  spots = correct::HideUnderLids(spots, o.lids);
  cv::Mat image = correct::RenderSpotImage(spots, device.camera.width_px, device.camera.height_px, o);
  if (cache.size() >= 32) cache.clear();
  cache.emplace(line, image);
  return image;
}

std::vector<pipeline::BallImage> ReadBalls(const std::string& text) {
  std::vector<pipeline::BallImage> balls;
  for (size_t start = 0; start <= text.size() && balls.size() < kMaxBalls;) {
    size_t end = text.find(kSeparator, start);
    if (end == std::string::npos) end = text.size();
    const std::string part = text.substr(start, end - start);
    const size_t newline = part.find('\n');
    const std::string line = part.substr(0, newline);
    const std::string bytes = newline == std::string::npos ? std::string() : part.substr(newline + 1);
    const BallLine b = ParseLine(line);
    pipeline::BallImage ball;
    ball.name = "ball-" + std::to_string(balls.size() + 1) + ".png";
    ball.radius_mm = b.radius_mm;
    const auto& camera = Nominal().camera;
    if (bytes.empty()) {
      ball.image = Render(line, b);
    } else {
      ball.image = imageio::DecodeImage(bytes, imageio::Channels::kAsStored, ball.name);
      imageio::RequireSize(ball.image, ball.name, camera.width_px, camera.height_px, "fuzz-device.json");
    }
    balls.push_back(std::move(ball));
    start = end + std::string(kSeparator).size();
  }
  return balls;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  pipeline::DeviceCalibration result;
  try {
    const auto balls = ReadBalls(fuzz::Text(data, size));
    result = pipeline::CalibrateDevice(balls, Nominal(), Config(), calib::DeviceFitOptions{});
  } catch (const util::InputError&) {
    return 0;
  } catch (const std::runtime_error& e) {
    if (std::string(e.what()).find("could not be indexed") == std::string::npos) throw;
    return 0;
  }
  if (!result.fit.ok) return 0;
  // What `device calibrate` writes: every number finite (std::runtime_error otherwise, uncaught here: a defect),
  // and the file reads back through the one device reader (util::InputError uncaught: a defect).
  const nlohmann::json calibration = pipeline::DeviceCalibrationJson(result);
  util::RequireFiniteNumbers(calibration);
  (void)model::ParseDevice(model::DeviceToJson(result.fit.device, calibration), "written-device.json");
  return 0;
}

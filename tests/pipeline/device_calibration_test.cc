// The device model (camera + distortion + screen pose) and its calibration from reference-ball images.
#include "pipeline/device_calibration.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "model/config.h"
#include "model/device.h"
#include "pipeline/measure_spots.h"
#include "tests/pipeline/device_fixtures.h"
#include "topo/power_map.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

using testing::DrawDevice;
using testing::NominalDevice;
using testing::PaperConfig;



TEST(DeviceModel, NominalDeviceReproducesTheDesignImageExactly) {
  const auto config = PaperConfig();
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  const model::Surface cornea = model::Biconic{config.cornea};
  const auto direct = model::SynthesizeImage(cornea, model::Topographer{config.topographer}, design.targets);
  auto nominal = NominalDevice();
  nominal.camera.a_mm = config.topographer.a_mm;
  const auto through = model::SynthesizeImage(cornea, nominal, config.topographer, design.targets);
  ASSERT_EQ(direct.spots.size(), through.spots.size());
  for (size_t i = 0; i < direct.spots.size(); ++i) {
    EXPECT_EQ(direct.spots[i].position_mm, through.spots[i].position_mm);  // bit for bit: the same computation
  }
}

TEST(DeviceModel, ScreenPoseIsARigidMotionAboutThePinholePlane) {
  model::ScreenPose pose{0.7, -0.4, 0.9, 0.1, -0.2, 0.3, 1.0};
  const double pivot_z = -70.0;
  // The pivot itself only translates.
  const Eigen::Vector3d pivot(0, 0, pivot_z);
  EXPECT_LT((pose.Apply(pivot, pivot_z) - (pivot + Eigen::Vector3d(0.1, -0.2, 0.3))).norm(), 1e-14);
  // Distances are preserved (rotation + translation).
  const Eigen::Vector3d p(3.0, -1.0, -80.0), q(-2.0, 4.0, -75.0);
  EXPECT_NEAR((pose.Apply(p, pivot_z) - pose.Apply(q, pivot_z)).norm(), (p - q).norm(), 1e-12);
  // A pure rx rotates +y towards +z (right-handed about x).
  model::ScreenPose rx{90.0, 0, 0, 0, 0, 0, 1.0};
  const Eigen::Vector3d moved = rx.Apply(pivot + Eigen::Vector3d(0, 1, 0), pivot_z);
  EXPECT_LT((moved - (pivot + Eigen::Vector3d(0, 0, 1))).norm(), 1e-14);
}

// The templated projection the fit differentiates agrees with the simulation's independent composition
// (SynthesizeImage through the device + Device::PixelOf) — to the Newton solves' floor.
constexpr double kProjectionAgreementPx = 1e-8;

TEST(DeviceModel, BallProjectionAgreesWithTheSimulationAndItsDerivativesWithFiniteDifferences) {
  const auto config = PaperConfig();
  std::mt19937 rng(7);
  const auto device = DrawDevice(rng);
  const Eigen::Vector3d vertex(0.21, -0.13, 0.17);
  const double radius = 6.5;
  const auto simulated = SimulateBall(device, config, radius, vertex);
  ASSERT_EQ(simulated.spots_px.size(), 624u);
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  const auto setup = model::ProjectionSetupOf(device, config.topographer);
  const auto pose = device.screen.AsArray();
  const double scale = device.screen.radial_scale;
  const double pp[2] = {device.camera.principal_point_px.x(), device.camera.principal_point_px.y()};
  const double a = device.camera.a_mm;
  const double sigma = std::get<model::SeidelParams>(device.distortion).sigma_per_mm2;
  double worst = 0;
  for (size_t i = 0; i < design.targets.size(); ++i) {
    const auto& t = design.targets[i];
    const Eigen::Vector2d init = t.on_sphere_mm.head<2>() * radius / config.topographer.re_mm + vertex.head<2>();
    double px[2];
    ASSERT_TRUE(model::ProjectBallSpot(setup, pose.data(), &scale, pp, &a, &sigma, vertex.data(), radius,
                                       t.on_cone_mm.data(), init, px));
    ASSERT_EQ(simulated.spots_px[i].first, t.id);
    worst = std::max(worst, (Eigen::Vector2d(px[0], px[1]) - simulated.spots_px[i].second).norm());
  }
  EXPECT_LT(worst, kProjectionAgreementPx);

  // d pixel / d (rx, ball z) by jets against central differences, on an outer-ring spot.
  using J = ceres::Jet<double, 2>;
  const auto& t = design.targets.back();
  const Eigen::Vector2d init = t.on_sphere_mm.head<2>() * radius / config.topographer.re_mm + vertex.head<2>();
  J jpose[6], jscale(scale), jpp[2] = {J(pp[0]), J(pp[1])}, ja(a), jsigma(sigma), jball[3], jpx[2];
  for (int k = 0; k < 6; ++k) jpose[k] = J(pose[k]);
  jpose[0].v[0] = 1;
  for (int k = 0; k < 3; ++k) jball[k] = J(vertex[k]);
  jball[2].v[1] = 1;
  ASSERT_TRUE(model::ProjectBallSpot(setup, jpose, &jscale, jpp, &ja, &jsigma, jball, radius, t.on_cone_mm.data(),
                                     init, jpx));
  const auto project = [&](double drx, double dz) {
    auto p = pose;
    p[0] += drx;
    Eigen::Vector3d v = vertex;
    v.z() += dz;
    double out[2];
    EXPECT_TRUE(model::ProjectBallSpot(setup, p.data(), &scale, pp, &a, &sigma, v.data(), radius,
                                       t.on_cone_mm.data(), init, out));
    return Eigen::Vector2d(out[0], out[1]);
  };
  const double h_deg = 1e-5, h_mm = 1e-6;
  const Eigen::Vector2d d_rx = (project(h_deg, 0) - project(-h_deg, 0)) / (2 * h_deg);
  const Eigen::Vector2d d_z = (project(0, h_mm) - project(0, -h_mm)) / (2 * h_mm);
  for (int c = 0; c < 2; ++c) {
    // Central differences are good to ~1e-7 relative here (step^2 truncation, 1e-16/step rounding).
    EXPECT_NEAR(jpx[c].v[0], d_rx[c], 1e-6 * std::max(1.0, std::abs(d_rx[c])));
    EXPECT_NEAR(jpx[c].v[1], d_z[c], 1e-6 * std::max(1.0, std::abs(d_z[c])));
  }
  EXPECT_GT(d_rx.norm(), 1.0);  // a 1-deg tilt moves the spot by pixels: the derivative is not trivially zero
}

TEST(DeviceFile, RoundTripsAndRefusesBadInput) {
  std::mt19937 rng(3);
  const auto device = DrawDevice(rng);
  const auto text = model::DeviceToJson(device, nlohmann::json{{"chi2_per_dof", 1.02}});
  const auto read = model::ParseDevice(text, "dev.json");
  EXPECT_EQ(model::DeviceToJson(read.device, read.calibration), text);
  EXPECT_EQ(read.device.screen.rx_deg, device.screen.rx_deg);
  EXPECT_EQ(read.device.camera.principal_point_px, device.camera.principal_point_px);
  const auto error_of = [](const std::string& t) -> std::string {
    try {
      model::ParseDevice(t, "dev.json");
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  };
  auto j = nlohmann::json::parse(text);
  auto bad = j;
  bad["screen_pose"]["rx_deg"] = 45.0;
  EXPECT_EQ(error_of(bad.dump()), "dev.json: screen_pose.rx_deg: must be in [-10, 10] (got 45)");
  bad = j;
  bad["distortion"]["centre_mm"] = {-1e308, 0.0};  // rendered 624 spots at NaN, exit 0
  EXPECT_EQ(error_of(bad.dump()),
            "dev.json: distortion.centre_mm: must lie within 10 mm of the axis in x and y (got [-1e+308, 0])");
  bad = j;
  bad["screen_pose"]["tilt"] = 1.0;
  EXPECT_EQ(error_of(bad.dump()), "dev.json: screen_pose.tilt: unknown key");
  bad = j;
  bad["camera"]["a_mm"] = -5.2;
  EXPECT_NE(error_of(bad.dump()).find("a_mm: must be > 0"), std::string::npos);
  bad = j;
  bad["format_version"] = 2;
  EXPECT_NE(error_of(bad.dump()).find("format_version: this topocal reads version 1"), std::string::npos);
  bad = j;
  bad.erase("camera");
  EXPECT_EQ(error_of(bad.dump()), "dev.json: camera: missing");
  bad = j;
  bad["distortion"]["model"] = "fisheye";
  EXPECT_EQ(error_of(bad.dump()),
            "dev.json: distortion.model: must be \"seidel\" or a lens model (brown, rational8) (got \"fisheye\")");
  // A lens model's coefficient count is its own: eight for the rational model, which round-trips whole.
  model::Device rational = device;
  model::LensParams lens;
  lens.model = model::RationalPolynomial{};
  lens.focal_mm = rational.camera.a_mm;
  lens.k = {-0.02, 0.004, 1e-4, -2e-4, -1e-3, 0.01, 0.002, -5e-4};
  rational.distortion = lens;
  const auto rational_text = model::DeviceToJson(rational);
  const auto rational_read = model::ParseDevice(rational_text, "rational.json").device;
  const auto& read_lens = std::get<model::LensParams>(rational_read.distortion);
  EXPECT_TRUE(std::holds_alternative<model::RationalPolynomial>(read_lens.model));
  EXPECT_EQ(read_lens.k, lens.k);
  EXPECT_EQ(model::DeviceToJson(rational_read), rational_text);
  bad = nlohmann::json::parse(rational_text);
  bad["distortion"]["k"] = {1.0, 2.0, 3.0, 4.0, 5.0};
  EXPECT_NE(error_of(bad.dump()).find("distortion.k"), std::string::npos) << error_of(bad.dump());
  EXPECT_NE(error_of("{\"format\": \"topocal-device\", \"format_version\": 1e999}").find("beyond the range of a double"),
            std::string::npos);
  // Input that could crash or fool a parser: nesting beyond the limit (a stack overflow in nlohmann's recursion),
  // a key given twice (silently the last one before).
  EXPECT_NE(error_of(std::string(100000, '[') + std::string(100000, ']')).find("nested deeper than 64 levels"),
            std::string::npos);
  bad = j;
  std::string twice = bad.dump();
  twice.insert(1, "\"format_version\": 7, ");
  EXPECT_EQ(error_of(twice), "dev.json: format_version: given twice in one object");
  // A camera file given where a device is expected is a clear error; a device file works as a camera file.
  EXPECT_NE(error_of(model::TopographerCameraToJson(device.camera)).find("format: missing"), std::string::npos);
  EXPECT_EQ(model::ParseTopographerCamera(text, "dev.json").principal_point_px, device.camera.principal_point_px);
}

}  // namespace
}  // namespace topocal::pipeline

#include "correct/spot_truth.h"

#include <fmt/format.h>

#include <optional>

#include "model/null_screen_layout.h"

namespace topocal::correct {

SpotTruth SpotsOnSensor(const model::Surface& cornea, const model::IdealImageParams& ideal,
                        const model::TopographerParams& topographer, const model::Distortion& distortion,
                        const model::TopographerCamera& camera) {
  model::Device device = model::NominalDevice(camera);
  device.camera.a_mm = topographer.a_mm;
  device.distortion = distortion;
  return SpotsOnSensor(cornea, ideal, topographer, device);
}

SpotTruth SpotsOnSensor(const model::Surface& cornea, const model::IdealImageParams& ideal,
                        const model::TopographerParams& topographer, const model::Device& device) {
  const model::Topographer design_topo{topographer};
  const model::Topographer topo{device.AsBuilt(topographer)};
  const auto& camera = device.camera;
  const auto design = model::DesignNullScreen(ideal, topographer);
  const auto image = model::SynthesizeImage(cornea, device, topographer, design.targets);
  SpotTruth out;
  out.failures = design.failures;
  out.failures.insert(out.failures.end(), image.failures.begin(), image.failures.end());
  const double radius_mm = ideal.spot_radius_um * 1e-3;
  // Sensor pixel of an ideal-image point, through cornea and distortion; nullopt if any step fails.
  const auto to_px = [&](const Eigen::Vector2d& ideal_mm, const Eigen::Vector2d& surface_guess) -> std::optional<Eigen::Vector2d> {
    const auto t = model::TraceIdealPoint(design_topo, ideal_mm);
    if (!t) return std::nullopt;
    const Eigen::Vector3d placed = device.screen.Apply(t->on_cone_mm, -topographer.b_mm);
    const auto p2 = model::SolveReflectionPoint(cornea, topo, placed, surface_guess);
    if (!p2) return std::nullopt;
    return device.PixelOf(topo.ImageOf(*p2));
  };
  std::vector<Eigen::Vector2d> ideal_of(image.spots.size());
  for (const auto& t : design.targets) {
    for (size_t k = 0; k < image.spots.size(); ++k) {
      if (image.spots[k].id == t.id) ideal_of[k] = t.ideal_mm;
    }
  }
  for (size_t k = 0; k < image.spots.size(); ++k) {
    const auto& s = image.spots[k];
    if (model::IsOrientationKeySpot(ideal, s.id)) continue;  // a gap of the orientation key: not on the screen
    const Eigen::Vector2d d_mm = model::Distort(device.distortion, s.position_mm);
    SpotToRender r;
    r.id = s.id;
    r.centre_px = camera.PixelFromDetectionPlane(d_mm);
    const Eigen::Vector2d guess = s.on_surface_mm.head<2>();
    const auto xp = to_px(ideal_of[k] + Eigen::Vector2d(radius_mm, 0), guess);
    const auto xm = to_px(ideal_of[k] - Eigen::Vector2d(radius_mm, 0), guess);
    const auto yp = to_px(ideal_of[k] + Eigen::Vector2d(0, radius_mm), guess);
    const auto ym = to_px(ideal_of[k] - Eigen::Vector2d(0, radius_mm), guess);
    if (xp && xm && yp && ym) {
      // Central differences over +-radius: J * radius directly.
      r.shape_px.col(0) = (*xp - *xm) / 2.0;
      r.shape_px.col(1) = (*yp - *ym) / 2.0;
    } else {
      r.shape_px = Eigen::Matrix2d::Identity() * (radius_mm / camera.PitchMm());
    }
    out.spots.push_back(r);
    out.position_mm.push_back(d_mm);
  }
  return out;
}

std::string SpotTruthCsv(const std::vector<SpotToRender>& spots, const model::TopographerCamera& camera) {
  std::string csv = "ring,index,x_px,y_px,x_mm,y_mm\n";
  for (const auto& s : spots) {
    const Eigen::Vector2d mm = camera.DetectionPlaneFromPixel(s.centre_px);
    csv += fmt::format("{},{},{:.6f},{:.6f},{:.9f},{:.9f}\n", s.id.ring, s.id.index, s.centre_px.x(), s.centre_px.y(),
                       mm.x(), mm.y());
  }
  return csv;
}

}  // namespace topocal::correct

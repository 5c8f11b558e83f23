#include "topo/image_ellipse.h"

namespace topocal::topo {

std::optional<model::Ellipse> FitImageContour(const std::vector<model::ImageSpot>& spots, int outer_ring) {
  std::vector<Eigen::Vector2d> boundary;
  for (const auto& s : spots) {
    if (s.id.ring == outer_ring) boundary.push_back(s.position_mm);
  }
  return model::FitEllipseDirect(boundary);
}

}  // namespace topocal::topo

#pragma once
// Direct least-squares ellipse fit (Fitzgibbon, Pilu & Fisher 1999 — the paper's ref. 24), in the numerically
// stable partitioned form of Halir & Flusser (1998). Orientation convention of paper Eq. 17: beta is the angle of
// the semi-major axis a from +x, counter-clockwise, in (-90, 90] degrees.
#include <optional>
#include <vector>

#include <Eigen/Core>

namespace topocal::model {

struct Ellipse {
  Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();
  double a_mm = 0;  // semi-major
  double b_mm = 0;  // semi-minor
  double beta_deg = 0;
  double AreaMm2() const { return M_PI * a_mm * b_mm; }
};

// nullopt for fewer than 5 points or a degenerate (non-elliptic) configuration.
std::optional<Ellipse> FitEllipseDirect(const std::vector<Eigen::Vector2d>& points_mm);

}  // namespace topocal::model

#pragma once
// The summary numbers a keratoconus or refractive-surgery clinic reads, from a power map and a
// surface, limited to the radius the data support (never extrapolated).
//
// Definitions (docs/reconstruction.md, "Clinical indices"), angles counter-clockwise from +x in the instrument
// frame, "superior" = +y (the topographer's image is not mirrored: docs/camera-conventions.md):
//  * sim-K: for each meridian theta in [0, 180) the mean axial power of theta and theta + 180 over the ring
//    sim_k_inner_mm <= rho <= sim_k_outer_mm (0.5-1.5 mm: the 1-3 mm diameter zone a keratometer reads); steep K is
//    the largest, flat K the meridian 90 deg away (the orthogonal pair of a regular astigmatism).
//  * Kmax: the largest axial power within the supported radius, and where it is (x, y).
//  * Best-fit sphere (BFS): a sphere with free centre and radius fitted to the sag over the disc of bfs_radius_mm
//    (limited to the supported radius); elevation = how far the surface stands in front of the sphere (towards the
//    camera, i.e. -z), in um; its peak (largest elevation) and where it is.
//  * I-S (Rabinowitz-McDonnell): mean axial power of 5 points on the inferior half minus 5 on the superior half, at
//    rho = is_radius_mm, 30 deg apart (inferior 210..330 deg, superior 30..150 deg).
#include <string>

#include <Eigen/Core>
#include <cmath>

#include "topo/power_map.h"

namespace topocal::topo {

struct ClinicalOptions {
  double sim_k_inner_mm = 0.5;
  double sim_k_outer_mm = 1.5;
  double bfs_radius_mm = 4.0;   // 8 mm zone, the usual elevation display
  double bfs_step_mm = 0.2;     // sampling of the BFS fit (~1,250 points over 8 mm); the peak is refined to 0.01 mm
  double is_radius_mm = 1.5;    // 3 mm zone
};

// The grid on which the elevation peak's location is refined (its reading's resolution).
inline constexpr double kElevationPeakStepMm = 0.01;
// A second peak: the highest value this far or farther from a peak's location (ClinicalIndices::*_runner_up_*).
inline constexpr double kPeakSeparationMm = 1.0;

struct ClinicalIndices {
  double supported_radius_mm = 0;  // indices use data within this radius only
  double steep_k_D = 0, steep_axis_deg = 0, flat_k_D = 0, flat_axis_deg = 0;
  double CylinderD() const { return steep_k_D - flat_k_D; }
  double kmax_D = 0;
  Eigen::Vector2d kmax_at_mm = Eigen::Vector2d::Zero();
  // The highest axial power kPeakSeparationMm or farther from Kmax's location (-inf: none): when it lies within
  // Kmax's uncertainty, another place could be the maximum and the location is not determined.
  double kmax_runner_up_D = -INFINITY;
  double bfs_radius_mm = 0;
  Eigen::Vector3d bfs_centre_mm = Eigen::Vector3d::Zero();
  double bfs_zone_radius_mm = 0;   // the zone the sphere was fitted over
  double elevation_peak_um = 0;    // largest elevation above the BFS within the zone
  Eigen::Vector2d elevation_peak_at_mm = Eigen::Vector2d::Zero();
  double elevation_runner_up_um = -INFINITY;  // as kmax_runner_up_D, for the elevation peak
  double elevation_rms_um = 0;     // rms elevation over the zone (0 for a sphere)
  double inferior_superior_D = 0;
  bool is_available = false;       // false when is_radius_mm lies beyond the supported radius
};

// `axial` is the axial power map of the surface (its samples beyond supported_radius_mm are ignored); `surface`
// gives the sag for the BFS. Returns false with a reason when the supported area is too small for the sim-K ring
// or the BFS fit fails.
bool ComputeClinicalIndices(const PowerMaps& axial, const SurfaceEvaluator& surface, double supported_radius_mm,
                            const ClinicalOptions& options, ClinicalIndices* out, std::string* why = nullptr);

}  // namespace topocal::topo

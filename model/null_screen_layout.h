#pragma once
// The printable null screen: each ideal-image spot's small circle traced back to its outline on the cone, and the
// cone unrolled flat at 1:1 scale. Pure geometry; drawing it (SVG) is plot/null_screen_svg.h.
//
// Spot outline: the circle of radius `spot_radius_um` around an ideal spot centre on the detection plane is sampled
// at `outline_points` points; each point is traced backwards exactly as DesignNullScreen traces the centre
// (Eq. 3: through the pinhole, Eq. 5-7: onto the reference sphere, Eq. 8: reflected, Eq. 9-11: onto the cone).
// The result is the elongated, ellipse-like closed curve on the cone that images onto the circle.
//
// Development of the cone (apex A = (0, 0, z_c), semi-angle phi_c). A point P on the cone has
//   slant distance  s   = |P - A| = (z - z_c) / cos(phi_c)          (along the generator through P)
//   azimuth         phi = atan2(y, x)                                (about the z axis, from +x towards +y)
// The development is the circular sector of angle 2 pi sin(phi_c); P maps to the plane point with polar
// coordinates (s, psi), psi = (phi - phi_cut) sin(phi_c), phi - phi_cut taken in [0, 2 pi):
//
//                      y (paper)                    psi = sector angle: the other edge of the seam
//                      ^       _.-'                 (joins the cut edge when the sheet is rolled up)
//                      |   _.-'   outer rim: s_outer (towards the eye)
//                      |.-'  .-'
//                      | .-'   inner rim: s_inner (towards the camera)
//                  apex+-------------------> x (paper)   psi = 0: the cut edge, generator at azimuth phi_cut
//
// The map is an isometry (lengths along generators and along the circles z = const are preserved) and it is
// orientation-preserving with the paper's +z (the printed face, towards the viewer) carried to the cone's inward
// normal: printed face up in this frame, rolled with the print inside, the pattern lands where the design puts it.
// Note that y points up here; an SVG writer (y down) must flip y.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "model/config.h"
#include "model/null_screen.h"
#include "util/io.h"

namespace topocal::model {

struct NullScreenLayoutOptions {
  int outline_points = 64;     // samples of each spot circle (the outline is the closed polygon through them)
  double rim_margin_mm = 5.0;  // extra paper beyond the outermost outline points, at both rims
  // The cut (seam) generator's azimuth. nullopt: chosen automatically where the seam crosses the fewest outlines,
  // and among those where it keeps the largest clearance from them.
  std::optional<double> cut_azimuth_rad;
  bool IsValid(std::string* why) const;
};

// The development of the cone: maps between cone points and the flat sheet.
struct ConeDevelopment {
  double apex_z_mm = 0.0;          // z_c
  double semi_angle_rad = 0.0;     // phi_c
  double cut_azimuth_rad = 0.0;    // phi_cut: the generator along which the cone is cut open
  double SectorAngleRad() const;   // 2 pi sin(phi_c)
  double SlantMm(const Eigen::Vector3d& on_cone_mm) const;  // s
  // (s, psi) -> plane point; the azimuth is wrapped into [phi_cut, phi_cut + 2 pi).
  Eigen::Vector2d Unroll(const Eigen::Vector3d& on_cone_mm) const;
  // The same, with the azimuth unwrapped to the branch nearest `near_psi_rad` (so a curve crossing the seam stays
  // in one piece; psi may then leave [0, sector angle)).
  Eigen::Vector2d UnrollNear(const Eigen::Vector3d& on_cone_mm, double near_psi_rad) const;
  double PsiRad(const Eigen::Vector3d& on_cone_mm) const;  // psi in [0, sector angle)
  // Inverse of Unroll: the cone point of a sheet point (any psi; psi / sin(phi_c) is the azimuth from the cut).
  Eigen::Vector3d RollUp(const Eigen::Vector2d& sheet_mm) const;
};

struct SpotOutline {
  SpotId id;
  Eigen::Vector3d target_on_cone_mm = Eigen::Vector3d::Zero();  // the designed target point (image of the spot centre)
  std::vector<Eigen::Vector3d> on_cone_mm;     // outline_points points, closed polygon (last joins first)
  Eigen::Vector2d target_sheet_mm = Eigen::Vector2d::Zero();  // target on the sheet
  std::vector<Eigen::Vector2d> sheet_mm;       // outline on the sheet, unwrapped next to the target (one piece)
  bool crosses_seam = false;                   // part of the outline lies beyond psi = 0 or psi = sector angle
};

struct NullScreenLayout {
  ConeDevelopment development;
  double inner_slant_mm = 0.0;  // sheet radius of the inner rim (camera end)
  double outer_slant_mm = 0.0;  // sheet radius of the outer rim (eye end)
  std::vector<SpotOutline> outlines;
  std::vector<SpotFailure> failures;  // spots whose centre or any outline point could not be traced to the cone
  // Pairs of spots whose ideal-image circles overlap (centre distance < 2 spot radii): their outlines on the cone
  // overlap too (the trace is one-to-one), and the printed ellipses merge. 0 for a usable spot radius.
  int overlapping_pairs = 0;
};

// The orientation key (config ideal_image.orientation_key; docs/image-orientation.md): three spots left out of the
// printed screen, on three different rings at about 30 %, 50 % and 70 % of the pattern's radius, at the angles
// nearest 0, 90 and 225 deg (ideal-image frame, from +x towards +y). No rotation by 90-deg steps and no mirror maps
// this set of gaps onto itself (a symmetry would have to fix each gap, the rings being different, and no mirror
// axis holds two of these directions), so the gaps seen in an image tell which of the eight axis-aligned
// orientations it has. Empty when the key is off.
std::vector<SpotId> OrientationKeySpots(const IdealImageParams& ideal);
bool IsOrientationKeySpot(const IdealImageParams& ideal, const SpotId& id);

// Backward trace of one detection-plane point to the cone, step for step as DesignNullScreen does for spot
// centres. nullopt if the ray misses the reference sphere or the reflected ray misses the cone.
std::optional<Eigen::Vector3d> TraceImagePointToCone(const Topographer& topographer, const Eigen::Vector2d& image_mm);

// Lays out the whole null screen. Throws util::InputError if `options` is invalid (see IsValid).
NullScreenLayout LayoutNullScreen(const IdealImageParams& ideal, const TopographerParams& topographer,
                                  const NullScreenLayoutOptions& options = {});

}  // namespace topocal::model

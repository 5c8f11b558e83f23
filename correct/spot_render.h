#pragma once
// Synthetic sensor images of a spot pattern: the ground truth that detection and indexing are tested against.
//
// Each spot is drawn about its true centre in one of two ways (docs/camera-conventions.md, "Rendering"):
//  * kPsf: a point source blurred by an isotropic Gaussian PSF of psf_sigma_px, integrated exactly over each pixel's
//    area (separable erf differences) — the centre is the Gaussian's mean.
//  * kEllipse: the image of the spot's null-screen circle (ideal-image radius spot_radius_um), taken as the ideal
//    circle mapped through the local Jacobian of the imaging (cornea reflection + distortion + camera), i.e. a filled
//    ellipse `shape_px * unit disk` about the centre, its edge blurred by the Gaussian PSF (edge profile
//    Phi(distance inside the edge / psf_sigma_px)), integrated over each pixel by a symmetric 3x3 sub-pixel grid.
//    The centre is the image of the circle's centre under that affine map; the curvature of the true imaging over an
//    8 um circle (second-order terms) is neglected — it moves a spot's centroid by < 1e-3 px at the paper's scale.
// Then exposure (spot peak above background), Gaussian read noise and optional shot noise, seeded; quantised to
// 8 or 16 bits.
#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "model/null_screen.h"

namespace topocal::correct {

struct SpotToRender {
  model::SpotId id;                              // ring 0 marks a spurious glint
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();
  Eigen::Matrix2d shape_px = Eigen::Matrix2d::Zero();  // maps the unit disk onto the spot (kEllipse)
  double relative_brightness = 1.0;              // peak = relative_brightness * peak_dn
  double psf_sigma_px = 0;                       // 0: the options' psf_sigma_px (glints carry their own)
};

enum class SpotShape { kPsf, kEllipse };

// Lids over the pattern: an upper lid over the top `upper` fraction and a lower lid over the bottom `lower` fraction
// of the pattern's height (the image's top is the smallest v), each margin an edge that curves away from the
// pattern's centre. Fractions in [0, 1).
struct Lids {
  double upper = 0, lower = 0;
  double v_top_px = 0, v_bottom_px = 0, u_mid_px = 0;  // the pattern's extent (set by LidsOver)
  bool Hides(double u_px, double v_px) const;
  bool Any() const { return upper > 0 || lower > 0; }
};

// What a clinical capture adds over the pattern besides lids (capture issue, item 5), drawn by RenderSpotImage about
// the pattern's extent in `lids` (LidsOver):
//  * lashes: shadows hanging from the upper lid's margin (from just above the pattern without a lid), each a
//    curved band 2-5 % of the pattern's radius wide and 35-70 % of it long, letting lash_transmission through;
//  * iris: a textured annulus behind the pattern (0.35-1.3 pattern radii; radial streaks and grain, mean iris_dn
//    above background, +-40 %), the pupil dark;
//  * motion blur: the eye's movement during the exposure, a straight smear of motion_blur_px at motion_blur_deg
//    (from the image's +u axis), centred, so that the spots' centres stay the truth's.
struct Artefacts {
  int lashes = 0;
  double lash_transmission = 0.25;
  double iris_dn = 0;
  double motion_blur_px = 0, motion_blur_deg = 0;
  bool Any() const { return lashes > 0 || iris_dn > 0 || motion_blur_px > 0; }
};

struct SpotRenderOptions {
  SpotShape shape = SpotShape::kEllipse;
  double psf_sigma_px = 1.0;
  int bits = 16;                 // 8 or 16
  double background_dn = 1000;   // in the image's own digital numbers
  double peak_dn = 40000;        // spot level above background (kEllipse plateau, kPsf Gaussian peak)
  double read_noise_dn = 20;     // Gaussian, standard deviation
  double gain_e_per_dn = 0;      // > 0 adds shot noise of variance signal / gain (DN^2); 0: none
  // The lids' skin, drawn where `lids` hides the pattern: a level above the background and a smooth random texture
  // (standard deviation, DN) at the scale of a few spot spacings and finer, as skin, lashes' roots and the lid
  // margin's shading make it.
  Lids lids;
  double skin_dn = 0, skin_texture_dn = 0;
  Artefacts artefacts;
  uint32_t seed = 1;
  bool IsValid(std::string* why) const;
};

// Renders `spots` onto a width x height image (CV_8UC1 or CV_16UC1). Spots partly off the sensor are clipped.
cv::Mat RenderSpotImage(const std::vector<SpotToRender>& spots, int width_px, int height_px,
                        const SpotRenderOptions& options);

// Perturbs a spot list as a real image would: drops `drop_fraction` of the spots (chosen at random, seeded) and adds
// `glint_count` spurious blobs (ring 0, index 0..count-1) with random size (PSF 1-3 px) and brightness (0.5-1.5) at
// random positions within the pattern's bounding box grown by 20 %, each at least `min_glint_distance_px` from every
// spot centre (a glint on top of a spot would be one merged blob, which no detector can undo).
std::vector<SpotToRender> DropAndAddGlints(const std::vector<SpotToRender>& spots, double drop_fraction,
                                           int glint_count, double min_glint_distance_px, uint32_t seed);

// Defocus that grows towards the rim (a cornea's periphery lies off the camera's focal surface): each spot's PSF
// sigma runs linearly with its distance from the pattern's centre (lids' u_mid, mid-height) from `centre_px` there
// to `rim_px` at the pattern's radius (half its height), and beyond.
std::vector<SpotToRender> GrowDefocus(const std::vector<SpotToRender>& spots, const Lids& extent, double centre_px,
                                      double rim_px);

// Tear-film break-up: `patches` dry patches (radius 5-12 % of the pattern's radius) at random places within the
// pattern, seeded. A spot inside a patch is lost (probability 1/2) or smeared: its PSF 2.5x wider, half as bright.
// Glints are left as they are.
std::vector<SpotToRender> BreakTearFilm(const std::vector<SpotToRender>& spots, const Lids& extent, int patches,
                                        double psf_sigma_px, uint32_t seed);

Lids LidsOver(const std::vector<SpotToRender>& spots, double upper, double lower);
// The spots (and glints) the lids leave visible.
std::vector<SpotToRender> HideUnderLids(const std::vector<SpotToRender>& spots, const Lids& lids);

}  // namespace topocal::correct

#pragma once
// The harness configuration (docs/harness.md): which distortions and which assembly errors of the device, corneas,
// spot-position noise levels and calibration errors to sweep, and the clinical limits the inverse answer is asked for.
//
// Loading is strict like model::LoadConfig: an unknown key, a missing key, a mistyped or non-finite value, an empty
// list or a range with no value in it throws util::ConfigError whose message is one line "FILE: KEY: problem".
//
// Every list may be given explicitly ([v0, v1, ...]) or as a range
//   {"from": a, "to": b, "count": n, "spacing": "log" | "linear", "both_signs": false}
// (log: 0 < a <= b, n values geometrically spaced; both_signs adds -v for every v, listed from the most negative).
// The canonical form (CanonicalHarnessJson) has every range expanded, every default filled in and the design
// configuration inline; it is what shards carry and what their identity (SHA-256) is computed from.
#include <cstdint>
#include <iterator>
#include <string>
#include <vector>

#include "model/config.h"
#include "model/paper_topographer.h"

namespace topocal::harness {

// One distortion axis of the sweep: the true distortion is one coefficient of one model on the detection plane,
// about the design's distortion centre; the others are zero.
enum class DistortionFamily {
  kSeidelSigma,  // Seidel sigma (paper Eq. 18) with the design's M_T, mm^-2
  kBrownK1,      // Brown-Conrady k1 on normalised coordinates x / a (OpenCV convention, model/distortion.h)
  kBrownK2,      // Brown-Conrady k2
};
const char* DistortionFamilyName(DistortionFamily family);  // "seidel_sigma_per_mm2", "brown_k1", "brown_k2"

// One assembly axis of the sweep: the device as built differs from the nominal one (model::Device)
// by one error; the spots are imaged exactly through it and measured through the nominal device, i.e. uncorrected.
// Directional axes take magnitudes >= 0, each applied at every azimuth phi of `assembly.azimuths_deg`; the others
// take signed values. Frames and signs: docs/device.md.
enum class AssemblyAxis {
  kScreenTilt,          // screen_tilt_deg: theta >= 0 at azimuth phi: rx = theta cos phi, ry = theta sin phi
  kScreenRoll,          // screen_roll_deg: rz, signed
  kScreenDecentration,  // screen_decentration_mm: d >= 0 at azimuth phi: tx = d cos phi, ty = d sin phi
  kScreenAxial,         // screen_axial_mm: tz, signed (> 0: the cone sits further towards the eye)
  kPrincipalPoint,      // principal_point_offset_mm: p >= 0 on the sensor at azimuth phi (from +u towards +v):
                        //   the principal point moves by p (cos phi, sin phi) / pitch px
  kARelative,           // a_relative_error: the as-built a is a (1 + value), signed
};
inline constexpr AssemblyAxis kAssemblyAxes[] = {AssemblyAxis::kScreenTilt,         AssemblyAxis::kScreenRoll,
                                                 AssemblyAxis::kScreenDecentration, AssemblyAxis::kScreenAxial,
                                                 AssemblyAxis::kPrincipalPoint,     AssemblyAxis::kARelative};
inline constexpr int kNumAssemblyAxes = static_cast<int>(std::size(kAssemblyAxes));
const char* AssemblyAxisName(AssemblyAxis axis);  // the configuration key, e.g. "screen_tilt_deg"
const char* AssemblyAxisUnit(AssemblyAxis axis);  // "deg", "mm" or "" (relative)
bool IsDirectional(AssemblyAxis axis);            // tilt, decentration, principal point
// Largest magnitude accepted on each axis: far outside any assembly tolerance (a value beyond it is a wrong unit),
// and within what a device file accepts (docs/device.md).
double AssemblyAxisMaximum(AssemblyAxis axis);

struct HarnessCornea {
  std::string name;  // [A-Za-z0-9_.-]+, unique
  model::BiconicParams params;
};

struct HarnessLimits {
  double dk = 0.05;            // largest |k - k_truth| of either conic constant (docs/harness.md: source)
  double dP_D = 0.25;          // largest |P - P_truth| of the maps over the compared disc, diopters
  bool tangential_map = true;  // "dP_maps": "axial+tangential" (default) or "axial" (the tangential map not limited)
};

struct HarnessConfig {
  model::Config design;          // the topographer (ideal image, geometry, M_T, distortion centre, reconstruction)
  // Of the camera: noise is given in px, residuals are also reported in px.
  double pixel_pitch_um = model::kPaperPixelPitchUm;
  std::uint64_t seed = 1;
  // The distortion axes, each a list of coefficients of its family (any may be empty).
  std::vector<double> seidel_sigma_per_mm2;
  std::vector<double> brown_k1;
  std::vector<double> brown_k2;
  // The assembly axes, indexed by AssemblyAxis (any may be empty; at least one distortion or assembly value).
  std::vector<double> assembly[kNumAssemblyAxes];
  std::vector<double> assembly_azimuths_deg;  // directions of the directional axes, [0, 360); default 0, 45, ..., 315
  std::vector<HarnessCornea> corneas;         // default: the design's own cornea, named "design"
  std::vector<double> noise_px;               // standard deviation of the spot position per axis, >= 0
  int noise_draws = 1;                        // seeded draws per noise level > 0 (a noise of 0 is drawn once)
  std::vector<double> calibration_errors;  // relative error e of the calibrated coefficient, >= -1 (-1: uncorrected);
                                           // needed with distortion axes only (assembly errors are never corrected)
  HarnessLimits limits;

  const std::vector<double>& Coefficients(DistortionFamily family) const;
  std::vector<double>& Coefficients(DistortionFamily family);
  const std::vector<double>& Errors(AssemblyAxis axis) const { return assembly[static_cast<int>(axis)]; }
  std::vector<double>& Errors(AssemblyAxis axis) { return assembly[static_cast<int>(axis)]; }
  bool HasDistortion() const;
  bool HasAssembly() const;
};

inline constexpr DistortionFamily kDistortionFamilies[] = {DistortionFamily::kSeidelSigma, DistortionFamily::kBrownK1,
                                                           DistortionFamily::kBrownK2};

// Loads H.json; a "design" given as a path is resolved against the directory of H.json. Throws util::ConfigError.
HarnessConfig LoadHarnessConfig(const std::string& path);
// `origin` names the source in messages; `base_dir` resolves a relative design path.
HarnessConfig ParseHarnessConfig(const std::string& json_text, const std::string& origin, const std::string& base_dir);

// The canonical JSON text (ranges expanded, defaults filled, design inline); parsing it gives the same config and
// the same text again.
std::string CanonicalHarnessJson(const HarnessConfig& config);
// Lower-case hex SHA-256 of CanonicalHarnessJson: the identity of a sweep, stored in every shard.
std::string HarnessConfigSha256(const HarnessConfig& config);

}  // namespace topocal::harness

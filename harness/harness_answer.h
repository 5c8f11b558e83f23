#pragma once
// The inverse answer of the harness (docs/harness.md): the largest residual distortion that keeps every case —
// every cornea, noise level and draw, every distortion shape — within the limits |dk| <= limits.dk and
// |dP| <= limits.dP_D.
//
// Computed from the merged cases only (so a sharded run gives the same answer as a single run):
//  * u = max(|dk| / dk_limit, |dP| / dP_limit) per case (infinite when the reconstruction failed); a case is within
//    the limits when u <= 1.
//  * Cases are grouped by what the residual field looks like — cornea, distortion family, orientation of the
//    residual (sign of -e x coefficient: barrel or pincushion), noise level and draw — and sorted by their residual
//    (max displacement over the spot field, um). Within a group u grows ~linearly with the residual. Each group's
//    crossing is the linear interpolation of u = 1 between its last case within the limits (or, below its first
//    case, the zero-residual anchor: the worst u of the same cornea and noise level with no residual, or 0) and its
//    first case outside them; later cases of the group are not used (conservative).
//  * The answer is the smallest crossing over all groups. The grid bounds are reported beside it: every tested case
//    with a residual <= grid_all_pass_up_to_um is within the limits, and the smallest residual of a case outside
//    them is grid_first_failure_um.
//
// Per assembly axis the same construction with the error itself in place of the residual: cases
// of one axis are grouped by cornea, direction (azimuth on a directional axis, sign on the others), noise level and
// draw, sorted by |error| and anchored at the worst zero-error case of the same cornea and noise level; the axis'
// answer is its smallest crossing: the largest error that keeps |dk| and |dP| within the limits uncorrected.
#include <string>
#include <vector>

#include "harness/harness.h"

namespace topocal::harness {

// Residuals below this are "no residual": the Newton inverses of model/distortion.h close to 1e-12 mm = 1e-9 um,
// so e = 0 or a zero coefficient leaves ~1e-10 um; 1e-6 um (1 pm) is far below any distortion the sweep applies.
inline constexpr double kZeroResidualUm = 1e-6;

struct FamilyAnswer {
  DistortionFamily family = DistortionFamily::kSeidelSigma;
  bool found = false;          // some case of the family is outside the limits
  double residual_max_um = 0;  // its smallest crossing; when !found, the largest residual tested
};

struct AssemblyAnswer {
  AssemblyAxis axis = AssemblyAxis::kScreenTilt;
  bool found = false;                // some case of the axis is outside the limits (else a lower bound)
  bool noise_alone_exceeds = false;  // a zero-error case is outside the limits: the answer is 0
  double max_error = 0;              // the answer, in the axis' unit (|error|; when !found: the largest tested)
  double grid_all_pass_up_to = 0;    // every tested case of the axis with |error| up to this is within the limits
  double grid_first_failure = 0;     // smallest |error| of a case of the axis outside the limits (when found)
  double max_tested = 0;
  int limiting_case = -1;  // the first case outside the limits of the limiting group
  std::string limited_by;  // "dk", "dP" or "failure"
};

struct InverseAnswer {
  bool found = false;                // some case is outside the limits (else the answer is a lower bound)
  bool noise_alone_exceeds = false;  // a case without residual distortion is already outside the limits
  double residual_max_um = 0;        // the answer (when !found: the largest residual tested, a lower bound)
  double residual_max_px = 0;
  double sigma_equivalent_per_mm2 = 0;  // |sigma| of the Seidel distortion displacing the edge of the spot field
                                        // of the first cornea by residual_max_um
  double grid_all_pass_up_to_um = 0;    // every tested case with a residual up to this is within the limits
  double grid_first_failure_um = 0;     // smallest residual of a case outside the limits (when found)
  double max_tested_um = 0;
  int limiting_case = -1;  // the first case outside the limits of the limiting group
  std::string limited_by;  // "dk", "dP" or "failure" (reconstruction failed)
  // The distortion answer above covers the distortion cases only; the counts below cover every case.
  int cases_within = 0;
  int cases_outside = 0;
  int cases_failed = 0;                  // reconstruction or fit failed
  std::vector<FamilyAnswer> families;    // one per family present in the sweep
  std::vector<AssemblyAnswer> assembly;  // one per assembly axis present in the sweep
};

// Utilisation of the limits by one case: max(|dk| / dk, |dP| / dP); +inf when the case failed.
double LimitUtilisation(const HarnessCaseResult& c, const HarnessLimits& limits);

InverseAnswer ComputeInverseAnswer(const HarnessRun& run);

}  // namespace topocal::harness

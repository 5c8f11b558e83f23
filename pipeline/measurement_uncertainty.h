#pragma once
// Every number a measurement through a calibrated device reports, with its uncertainty
// (docs/uncertainty.md). Three sources, combined in quadrature (GUM, JCGM 100:2008 Sec. 5.1):
//
//   device   the device's full parameter covariance (device calibrate: screen pose, principal point, a,
//            distortion; weak directions included), carried by linear propagation: u^2 = J S J' evaluated as the sum,
//            over the eigen-directions v_j of S, of (q(theta + sqrt(l_j) v_j) - q(theta))^2 — one analysis per
//            direction, each starting from the measurement's own analysis;
//   spots    the spot-centre noise measured in this image: the configured spot uncertainty times the
//            reconstruction's adequacy ratio (the slope residual over the residual that configured noise would
//            leave, with the fit's degrees of freedom taken out), carried by seeded Monte Carlo draws of that noise
//            on every used spot. The surface model's inadequacy enters here: a residual the model leaves raises the
//            ratio and so the noise drawn (the biconic fit's own residual is not a source: the same cornea gives the
//            same best-fit biconic, however far from a biconic it is);
//   bias     a reading that is not linear in the spots shifts with the noise: a range or a maximum over a noisy map
//            (pv, Kmax) rises, a smoothing spline's peak falls. When the spot draws' mean shift stands out of their
//            scatter, the measurement's own bias (shift / (sqrt(2) - 1)) is counted, uncorrected;
//            With the smoothing spline the bias of a map's peaks and ranges is not revealed by the draws: those
//            quantities are marked lower_bound;
//   grid     a reading taken on the power map's samples (the sim-K axes on its meridians, the Kmax and elevation
//            peak locations at a sample) has the grid's resolution: step / sqrt(12).
//
// Reported as U = 2 u (k = 2). Quantities are named by where the reconstruct JSON holds them
// ("surface_fit.rx_mm", "clinical.sim_k.steep_D", ...). Axis angles are differenced modulo 180 degrees.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "model/config.h"
#include "model/device.h"
#include "pipeline/measure_spots.h"
#include "topo/analysis.h"
#include "util/io.h"

namespace topocal::pipeline {

struct QuantityUncertainty {
  std::string name;   // where the reconstruct JSON holds the value, e.g. "clinical.kmax.power_D"
  std::string unit;   // "mm", "D", "deg", "um" or "" (a conic constant)
  double value = 0;   // the measurement's value
  // Standard uncertainties (k = 1) of each source (see above).
  double u_device = 0, u_spots = 0, u_bias = 0, u_resolution = 0;
  double expanded = 0;  // U = 2 sqrt(u_device^2 + u_spots^2 + u_bias^2 + u_resolution^2)
  // false: the data do not determine this reading (a peak's location when a second peak, kPeakSeparationMm or
  // more away, lies within the peak value's U): expanded is NaN and the value must not be read as a measurement.
  bool determined = true;
  // true: U leaves out a bias the noise draws do not reveal, and is a lower bound. Set for the readings of a map's
  // peaks and ranges (pv, Kmax and its margin, central power, I-S) when the surface is the smoothing spline: its REML
  // penalty flattens a cone by an amount that depends on the noise already in the image (docs/uncertainty.md:
  // coverage 74-88 % for these where 93-97 % is due).
  bool lower_bound = false;
};

struct MeasurementUncertainty {
  bool device_covariance = false;    // false: the device file has none; the device's part is unknown, not zero
  std::string no_device_covariance;  // why there is none (set by the caller, who knows where the device came from)
  std::vector<std::string> device_parameters;  // the covariance's parameters
  int device_directions = 0;         // eigen-directions with a spread, each one analysis
  bool device_monte_carlo = false;   // the device's part by Monte Carlo draws (UncertaintyOptions::device_draws)
  int device_analyses = 0;           // directions or draws that reconstructed
  double configured_spot_sigma_um = 0;
  double spot_sigma_um = 0;          // measured in the image (the configured one times the adequacy ratio)
  int spot_draws = 0;                // Monte Carlo draws of the spot noise that reconstructed
  int failed_draws = 0;              // device directions or spot draws whose analysis failed (counted, not hidden)
  std::vector<QuantityUncertainty> quantities;
  // U (k = 2) of the axial power at each sample of the analysis's polar map (topo::PowerMaps layout), D.
  std::vector<double> axial_expanded_D;
  // Its rms (area-weighted) and its largest value over the disc the data support, D; the largest is what a clinical
  // reading is refused on (UncertaintyRefusal).
  double axial_rms_expanded_D = 0, axial_max_expanded_D = 0;
  const QuantityUncertainty* Find(const std::string& name) const;
};

struct UncertaintyOptions {
  int device_draws = 0;     // 0: the device's part by linear propagation; N: by N Monte Carlo draws (a cross-check)
  int spot_draws = 16;      // Monte Carlo draws of the spot noise (the relative precision of u_spots ~ 1/sqrt(2 n))
  std::uint32_t seed = 1;   // draw i takes its normals from std::seed_seq{seed, i}: identical whatever `jobs` is
  int jobs = 0;             // threads (<= 0: every core)
};

// The numbers of an analysis by their JSON names, with their units; clinical ones only when clinical_ok. Axis
// angles are marked periodic (180 deg).
struct NamedQuantity {
  std::string name, unit;
  double value = 0;
  bool axis = false;        // an axis angle: differences are taken modulo 180 deg
  double step = 0;          // the reading's grid step (a sampled axis or location; 0: not sampled)
};
std::vector<NamedQuantity> ReportedQuantities(const topo::Analysis& analysis);

// `detected`: the identified spots as measured (distorted, on `device`'s detection plane); `nominal`: the
// measurement's analysis of them (AnalyzeThroughDevice after RejectSurfaceOutliers: only the spots it used are
// drawn). `covariance` nullopt: the device's part is left out and said so (device_covariance = false). Throws
// util::InputError for spot_draws < 2 and std::runtime_error when more than half of the analyses fail.
MeasurementUncertainty PropagateMeasurementUncertainty(const std::vector<model::PlaneSpot>& detected,
                                                       const model::Device& device,
                                                       const std::optional<model::DeviceCovariance>& covariance,
                                                       const model::Config& config, const topo::Analysis& nominal,
                                                       const UncertaintyOptions& options = {});

// The largest U (k = 2) of the axial map anywhere over the supported disc that a clinical reading can use. Kmax is
// read wherever the map peaks, so the map must be certain everywhere to the clinical-capture limit of |dKmax|
// (0.50 D, the capture issue's gate): a standard uncertainty U / 2 at that limit. A capture whose noise, identities
// or surface model leave the map less certain is refused (docs/uncertainty.md, "Refusal").
inline constexpr double kMaxAxialExpandedD = 1.0;

// Why the measurement's uncertainty leaves no clinical reading (nullopt: it does not).
std::optional<std::string> UncertaintyRefusal(const MeasurementUncertainty& u);

// A value and its expanded uncertainty as GUM prints them: U to two significant digits, the value rounded to the
// same decimal place ("8.3501 +- 0.0012"). U <= 0 or not finite: the value alone to `fallback_decimals`.
std::string FormatWithUncertainty(double value, double expanded, int fallback_decimals = 4);

}  // namespace topocal::pipeline

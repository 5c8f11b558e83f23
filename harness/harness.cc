#include "harness/harness.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>

#include "model/distortion.h"
#include "model/null_screen.h"
#include "pipeline/measure_spots.h"
#include "topo/analysis.h"
#include "util/parallel.h"

namespace topocal::harness {
namespace {

// SplitMix64 (Steele, Lea, Flood 2014): a bijective mixer, so distinct (seed, index) pairs give unrelated streams.
std::uint64_t SplitMix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Standard normal pairs by Box-Muller from std::mt19937_64, whose output sequence the C++ standard fixes (unlike
// std::normal_distribution's algorithm), so a seed gives the same noise with any standard library.
class NormalPairs {
 public:
  explicit NormalPairs(std::uint64_t seed) : engine_(seed) {}
  Eigen::Vector2d Next() {
    constexpr double kTwoPi = 6.283185307179586;
    const double u1 = (static_cast<double>(engine_() >> 11) + 1.0) * 0x1.0p-53;  // (0, 1]
    const double u2 = static_cast<double>(engine_() >> 11) * 0x1.0p-53;          // [0, 1)
    const double radius = std::sqrt(-2.0 * std::log(u1));
    return {radius * std::cos(kTwoPi * u2), radius * std::sin(kTwoPi * u2)};
  }

 private:
  std::mt19937_64 engine_;
};

model::Distortion DistortionOf(const model::Config& design, DistortionFamily family, double coefficient) {
  if (family == DistortionFamily::kSeidelSigma) {
    return design.distortion.SeidelAt(coefficient);
  }
  model::LensParams b;  // Brown-Conrady
  b.focal_mm = design.topographer.a_mm;  // OpenCV's normalised coordinates are x / a (docs/camera-conventions.md)
  b.centre_x_mm = design.distortion.centre_x_mm;
  b.centre_y_mm = design.distortion.centre_y_mm;
  b.k[family == DistortionFamily::kBrownK1 ? model::BrownConrady::kK1 : model::BrownConrady::kK2] = coefficient;
  return b;
}

// Largest |P - P_truth| over the samples of the two maps (same layout) within radius_mm.
double MaxAbsDifference(const std::vector<double>& a, const std::vector<double>& b, const topo::PowerMaps& layout,
                        double radius_mm) {
  // The samples within the radius are the first `inside` of every meridian (the radii grow with k): found once,
  // by the same test, instead of a division per sample (it was ~4 % of a harness case).
  int inside = 0;
  while (inside < layout.radial_samples && layout.RhoMm(inside) <= radius_mm) ++inside;
  double worst = 0;
  if (inside == 0) return worst;
  for (int j = 0; j < layout.meridians; ++j) {
    // Packed (the maps are finite: ComputePowerMaps fails otherwise, so the maximum is that of the scalar loop).
    const size_t row = static_cast<size_t>(j) * layout.radial_samples;
    const Eigen::Map<const Eigen::ArrayXd> pa(a.data() + row, inside), pb(b.data() + row, inside);
    worst = std::max(worst, (pa - pb).abs().maxCoeff());
  }
  return worst;
}

}  // namespace

double HarnessCaseResult::MaxAbsDk() const { return std::max(std::abs(dk_x), std::abs(dk_y)); }
double HarnessCaseResult::MaxAbsDP_D(const HarnessLimits& limits) const {
  return limits.tangential_map ? std::max(dP_axial_max_D, dP_tangential_max_D) : dP_axial_max_D;
}

std::uint64_t HarnessCaseSeed(std::uint64_t config_seed, int index) {
  return SplitMix64(SplitMix64(config_seed) ^ static_cast<std::uint64_t>(index));
}

std::vector<HarnessCaseSpec> EnumerateHarnessCases(const HarnessConfig& config) {
  int total = 0;
  return EnumerateHarnessCases(config, util::ShardSpec{0, 1}, &total);
}

std::vector<HarnessCaseSpec> EnumerateHarnessCases(const HarnessConfig& config, util::ShardSpec shard, int* total) {
  std::vector<HarnessCaseSpec> cases;
  int index = 0;
  // The noise levels and draws of one swept setting; only the shard's cases are built (a shard of a million-case run
  // spent 0.5 s and 90 MB on the other shards' cases).
  auto add = [&](const HarnessCaseSpec& setting) {
    for (const double noise : config.noise_px) {
      const int draws = noise > 0 ? config.noise_draws : 1;
      for (int d = 0; d < draws; ++d, ++index) {
        if (index % shard.count != shard.index) continue;
        HarnessCaseSpec s = setting;
        s.index = index;
        s.noise_px = noise;
        s.draw = d;
        s.seed = HarnessCaseSeed(config.seed, index);
        cases.push_back(s);
      }
    }
  };
  for (size_t c = 0; c < config.corneas.size(); ++c) {
    HarnessCaseSpec s;
    s.cornea = static_cast<int>(c);
    s.kind = HarnessCaseKind::kDistortion;
    for (const DistortionFamily family : kDistortionFamilies) {
      for (const double coefficient : config.Coefficients(family)) {
        for (const double e : config.calibration_errors) {
          s.family = family;
          s.coefficient = coefficient;
          s.calibration_error = e;
          add(s);
        }
      }
    }
    s = HarnessCaseSpec{};
    s.cornea = static_cast<int>(c);
    s.kind = HarnessCaseKind::kAssembly;
    for (const AssemblyAxis axis : kAssemblyAxes) {
      for (const double value : config.Errors(axis)) {
        s.axis = axis;
        s.error = value;
        s.azimuth_deg = 0;
        if (!IsDirectional(axis) || value == 0) {
          add(s);  // a zero magnitude has no direction: one case
          continue;
        }
        for (const double phi : config.assembly_azimuths_deg) {
          s.azimuth_deg = phi;
          add(s);
        }
      }
    }
  }
  *total = index;
  return cases;
}

model::Device HarnessNominalDevice(const HarnessConfig& config) {
  model::TopographerCamera camera;
  camera.pixel_pitch_um = config.pixel_pitch_um;
  camera.a_mm = config.design.topographer.a_mm;
  return model::NominalDevice(camera);
}

model::Device AssembledDevice(const HarnessConfig& config, const HarnessCaseSpec& spec) {
  model::Device device = HarnessNominalDevice(config);
  if (spec.kind != HarnessCaseKind::kAssembly) return device;
  const double phi = spec.azimuth_deg * M_PI / 180.0;
  const double v = spec.error;
  switch (spec.axis) {
    case AssemblyAxis::kScreenTilt:
      device.screen.rx_deg = v * std::cos(phi);
      device.screen.ry_deg = v * std::sin(phi);
      break;
    case AssemblyAxis::kScreenRoll:
      device.screen.rz_deg = v;
      break;
    case AssemblyAxis::kScreenDecentration:
      device.screen.tx_mm = v * std::cos(phi);
      device.screen.ty_mm = v * std::sin(phi);
      break;
    case AssemblyAxis::kScreenAxial:
      device.screen.tz_mm = v;
      break;
    case AssemblyAxis::kPrincipalPoint:
      device.camera.principal_point_px += Eigen::Vector2d(std::cos(phi), std::sin(phi)) * v / device.camera.PitchMm();
      break;
    case AssemblyAxis::kARelative:
      device.camera.a_mm *= 1.0 + v;
      break;
  }
  return device;
}

struct HarnessCaseRunner::CorneaData {
  model::Config config;                              // the design with this cornea
  std::vector<model::ImageSpot> spots;               // undistorted, noise-free
  std::map<model::SpotId, Eigen::Vector2d> spot_mm;  // the same, by identity
  topo::Analysis truth;
};

HarnessCaseRunner::HarnessCaseRunner(const HarnessConfig& config)
    : config_(config), nominal_(HarnessNominalDevice(config)) {
  const auto design = model::DesignNullScreen(config.design.ideal_image, config.design.topographer);
  if (design.targets.empty()) throw std::runtime_error("harness: no spot of the ideal image reaches the cone");
  targets_ = std::make_shared<const std::vector<model::TargetPoint>>(design.targets);
  const Eigen::Vector2d centre(config.design.distortion.centre_x_mm, config.design.distortion.centre_y_mm);
  for (const auto& cornea : config.corneas) {
    auto d = std::make_shared<CorneaData>();
    d->config = config.design;
    d->config.cornea = cornea.params;
    d->spots = model::SynthesizeImage(model::Biconic{cornea.params}, model::Topographer{config.design.topographer},
                                      design.targets)
                   .spots;
    for (const auto& s : d->spots) d->spot_mm.emplace(s.id, s.position_mm);
    const std::vector<model::PlaneSpot> measured = model::PlaneSpotsOf(d->spots);
    try {
      d->truth = topo::AnalyzeSpots(measured, design.targets, d->config, nullptr);
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(fmt::format("harness: cornea {}: the undistorted truth: {}", cornea.name, e.what()));
    }
    HarnessTruth t;
    t.cornea = cornea.name;
    t.fit = d->truth.surface_fit.params;
    t.covered_radius_mm = d->truth.covered_radius_mm;
    t.spots = static_cast<int>(d->spots.size());
    for (const auto& s : d->spots)
      t.spot_field_radius_mm = std::max(t.spot_field_radius_mm, (s.position_mm - centre).norm());
    t.pv_axial_D = d->truth.power.pv_axial_D;
    t.pv_tangential_D = d->truth.power.pv_tangential_D;
    truth_.push_back(t);
    data_.push_back(std::move(d));
  }
}

namespace {

// What Compare reads of a case's analysis: the biconic's parameters, the power maps and the covered radius. The
// biconic's standard deviations, the adequacy check and the clinical indices change none of these and are not
// computed (they were a fifth of a case). The biconic fit starts from the cornea's truth fit
// (AnalysisOptions::fit_start): 3-4 iterations instead of 5-21 (mean 9.3) over data/harness.json, the case
// 2.0 -> 1.8 ms; the fits agree with cold ones to 1e-8 in k and mm where |dk| is within the harness' limits, and
// to 4e-7 for the uncorrected cases 13 x beyond them (docs/performance.md). Starting the slope fits
// from the truth too (AnalysisOptions::start, as a unit's Monte Carlo draws do) was tried and dropped: no gain
// measured in the same run (12.4-12.7 ms per case either way; the profile still showed a QR in the cases, so the
// truth's factor did not serve them), while the results moved by up to 1e-11.
topo::AnalysisOptions CaseAnalysisOptions(const topo::Analysis& truth) {
  topo::AnalysisOptions o;
  o.stddev = o.adequacy = o.clinical = false;
  o.fit_start = &truth.surface_fit.params;
  return o;
}

}  // namespace

HarnessCaseResult HarnessCaseRunner::Run(const HarnessCaseSpec& spec) const {
  return spec.kind == HarnessCaseKind::kAssembly ? RunAssembly(spec) : RunDistortion(spec);
}

HarnessCaseResult HarnessCaseRunner::RunDistortion(const HarnessCaseSpec& spec) const {
  HarnessCaseResult r;
  r.spec = spec;
  const CorneaData& d = *data_.at(spec.cornea);
  const model::Distortion truth_distortion = DistortionOf(config_.design, spec.family, spec.coefficient);
  const model::Distortion estimated =
      DistortionOf(config_.design, spec.family, spec.coefficient * (1.0 + spec.calibration_error));
  const double pitch_mm = config_.pixel_pitch_um * 1e-3;
  NormalPairs noise(spec.seed);
  std::vector<model::PlaneSpot> measured;
  measured.reserve(d.spots.size());
  double sum2 = 0;
  int residual_spots = 0;
  for (const auto& s : d.spots) {
    const Eigen::Vector2d distorted = model::Distort(truth_distortion, s.position_mm);
    // Drawn for every spot (not only those that survive) so a case's noise does not depend on other failures.
    const Eigen::Vector2d z = spec.noise_px > 0 ? noise.Next() : Eigen::Vector2d::Zero();
    if (const auto back = model::Undistort(estimated, distorted)) {
      const double e_mm = (*back - s.position_mm).norm();
      r.residual_max_um = std::max(r.residual_max_um, e_mm * 1e3);
      sum2 += e_mm * e_mm;
      ++residual_spots;
    }
    const auto corrected = model::Undistort(estimated, distorted + spec.noise_px * pitch_mm * z);
    if (!corrected) {
      ++r.undistort_failures;
      continue;
    }
    measured.push_back({s.id, *corrected});
  }
  r.residual_rms_um = residual_spots > 0 ? std::sqrt(sum2 / residual_spots) * 1e3 : 0.0;
  r.spots_used = static_cast<int>(measured.size());
  if (residual_spots == 0 || measured.empty()) {
    r.failure = "no spot could be undistorted with the estimated coefficient";
    return r;
  }
  try {
    Compare(topo::AnalyzeSpots(measured, *targets_, d.config, nullptr, CaseAnalysisOptions(d.truth)), d, &r);
  } catch (const std::runtime_error& e) {
    r.failure = e.what();
  }
  return r;
}

HarnessCaseResult HarnessCaseRunner::RunAssembly(const HarnessCaseSpec& spec) const {
  HarnessCaseResult r;
  r.spec = spec;
  const CorneaData& d = *data_.at(spec.cornea);
  const model::Device device = AssembledDevice(config_, spec);
  // The cornea through the as-built device, exactly (the forward model of pipeline::SimulateBall).
  const auto image = model::SynthesizeImage(model::Biconic{config_.corneas[spec.cornea].params}, device,
                                            config_.design.topographer, *targets_);
  NormalPairs noise(spec.seed);
  std::vector<model::PlaneSpot> measured;
  measured.reserve(image.spots.size());
  double sum2 = 0;
  int residual_spots = 0;
  for (const auto& s : image.spots) {
    const Eigen::Vector2d pixel = device.PixelOf(s.position_mm);
    const Eigen::Vector2d z = spec.noise_px > 0 ? noise.Next() : Eigen::Vector2d::Zero();
    // Measured uncorrected: through the nominal device (no distortion: always invertible).
    const auto seen = nominal_.UndistortedOf(pixel);
    const auto noisy = nominal_.UndistortedOf(pixel + spec.noise_px * z);
    if (!seen || !noisy) {
      ++r.undistort_failures;
      continue;
    }
    if (const auto it = d.spot_mm.find(s.id); it != d.spot_mm.end()) {
      const double e_mm = (*seen - it->second).norm();
      r.residual_max_um = std::max(r.residual_max_um, e_mm * 1e3);
      sum2 += e_mm * e_mm;
      ++residual_spots;
    }
    measured.push_back({s.id, *noisy});
  }
  r.residual_rms_um = residual_spots > 0 ? std::sqrt(sum2 / residual_spots) * 1e3 : 0.0;
  r.spots_used = static_cast<int>(measured.size());
  if (measured.empty()) {
    r.failure = "no spot images through the as-built device";
    return r;
  }
  try {
    Compare(pipeline::AnalyzeThroughDevice(measured, nominal_, d.config, nullptr, CaseAnalysisOptions(d.truth)), d, &r);
  } catch (const std::runtime_error& e) {
    r.failure = e.what();
  }
  return r;
}

void HarnessCaseRunner::Compare(const topo::Analysis& a, const CorneaData& d, HarnessCaseResult* out) {
  HarnessCaseResult& r = *out;
  const auto& fit = a.surface_fit.params;
  const auto& truth = d.truth.surface_fit.params;
  r.dk_x = fit.kx - truth.kx;
  r.dk_y = fit.ky - truth.ky;
  r.dr_x_mm = fit.rx_mm - truth.rx_mm;
  r.dr_y_mm = fit.ry_mm - truth.ry_mm;
  r.compared_radius_mm = std::min({d.truth.covered_radius_mm, a.covered_radius_mm, a.power.radius_mm});
  r.dP_axial_max_D = MaxAbsDifference(a.power.axial_D, d.truth.power.axial_D, a.power, r.compared_radius_mm);
  r.dP_tangential_max_D =
      MaxAbsDifference(a.power.tangential_D, d.truth.power.tangential_D, a.power, r.compared_radius_mm);
  r.dpv_axial_D = a.power.pv_axial_D - d.truth.power.pv_axial_D;
  r.dpv_tangential_D = a.power.pv_tangential_D - d.truth.power.pv_tangential_D;
  const double values[] = {r.dk_x,
                           r.dk_y,
                           r.dr_x_mm,
                           r.dr_y_mm,
                           r.dP_axial_max_D,
                           r.dP_tangential_max_D,
                           r.dpv_axial_D,
                           r.dpv_tangential_D,
                           r.residual_max_um,
                           r.residual_rms_um};
  if (!std::all_of(std::begin(values), std::end(values), [](double v) { return std::isfinite(v); })) {
    const HarnessCaseSpec spec = r.spec;
    r = HarnessCaseResult{};
    r.spec = spec;
    r.failure = "a reconstructed value is not finite";
    return;
  }
  r.ok = true;
}

HarnessRun RunHarness(const HarnessConfig& config, util::ShardSpec shard, int jobs,
                      const std::function<void(std::size_t, std::size_t)>& progress) {
  HarnessRun run;
  run.config = config;
  run.config_sha256 = HarnessConfigSha256(config);
  run.shard = shard;
  const std::vector<HarnessCaseSpec> mine = EnumerateHarnessCases(config, shard, &run.total_cases);
  const HarnessCaseRunner runner(run.config);
  run.truth = runner.truth();
  run.cases.resize(mine.size());
  // Each case writes only its own slot, from its own seed: the results do not depend on the number of threads.
  std::atomic<size_t> done{0};
  util::ParallelFor(mine.size(), std::max(1, jobs), [&](size_t i) {
    run.cases[i] = runner.Run(mine[i]);
    if (progress) progress(++done, mine.size());
  });
  return run;
}

}  // namespace topocal::harness

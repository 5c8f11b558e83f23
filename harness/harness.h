#pragma once
// The harness (docs/harness.md): how much residual distortion, and how large an
// assembly error of the device, a topographer design tolerates.
//
// A case is one cornea x one true distortion (one coefficient of one family) x one relative calibration error e x
// one spot-position noise level x one seeded draw. For each case:
//   true spots (undistorted, noise-free) --Distort(true)--> + Gaussian noise (px x pitch, per axis)
//     --Undistort(estimated = true coefficient x (1 + e))--> reconstruction, biconic fit, power maps
// and the result is compared with the reconstruction of the undistorted, noise-free spots of the same cornea (the
// "truth reconstruction": what a perfect camera gives, so that the model error of the reconstruction itself is not
// charged to the distortion). The residual distortion of a case is Undistort(est, Distort(true, p)) - p over the
// noise-free spot field: e = 0 leaves none, e = -1 (no correction) leaves the whole distortion.
//
// An assembly case is one cornea x one assembly error of the device (one axis, one value, one azimuth) x one noise
// level x one draw: the cornea is imaged exactly through the as-built device (model::SynthesizeImage, then
// Device::PixelOf, the forward model of pipeline::SimulateBall), noise is added in pixels, and the pixels are
// measured through the nominal device (pipeline::AnalyzeThroughDevice), i.e. uncorrected, and compared with the
// same truth reconstruction. Its "residual" is the displacement of the noise-free measured spots from the truth
// spots on the detection plane.
//
// Cases are enumerated in a fixed order (cornea; then the distortion cases: family, coefficient, calibration error;
// then the assembly cases: axis, value, azimuth; then noise level, draw) with a global index; the noise of a case is
// drawn from a generator seeded by (config seed, case index) only, so any split into shards (index % N == i) merges
// into exactly the cases of a single run. A configuration without assembly axes enumerates exactly as before.
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "harness/harness_config.h"
#include "model/config.h"
#include "model/device.h"
#include "model/null_screen.h"
#include "topo/analysis.h"
#include "util/shard.h"

namespace topocal::harness {

enum class HarnessCaseKind { kDistortion, kAssembly };

struct HarnessCaseSpec {
  int index = 0;
  int cornea = 0;  // into HarnessConfig::corneas
  HarnessCaseKind kind = HarnessCaseKind::kDistortion;
  // Distortion cases:
  DistortionFamily family = DistortionFamily::kSeidelSigma;
  double coefficient = 0;        // true value, in the family's unit
  double calibration_error = 0;  // e: the correction uses coefficient x (1 + e)
  // Assembly cases:
  AssemblyAxis axis = AssemblyAxis::kScreenTilt;
  double error = 0;        // in the axis' unit (a magnitude >= 0 on a directional axis)
  double azimuth_deg = 0;  // its direction on a directional axis (0 when the magnitude is 0), else 0
  // Both:
  double noise_px = 0;
  int draw = 0;            // 0..noise_draws-1 (always 0 when noise_px = 0)
  std::uint64_t seed = 0;  // of this case's noise generator: from (config seed, index) only
};

struct HarnessCaseResult {
  HarnessCaseSpec spec;
  bool ok = false;      // false: the reconstruction or fit failed (counts as outside the limits)
  std::string failure;  // why, when !ok
  // Residual distortion over the noise-free spot field, on the detection plane (assembly cases: the displacement
  // of the noise-free spots measured through the nominal device from the truth spots).
  double residual_max_um = 0;
  double residual_rms_um = 0;
  int spots_used = 0;          // spots reconstructed
  int undistort_failures = 0;  // spots the estimated model could not undistort (dropped; assembly cases: 0, and
                               // spots the as-built device does not image are simply missing from spots_used)
  // Errors against the truth reconstruction of the same cornea (all zero when !ok).
  double dk_x = 0, dk_y = 0;
  double dr_x_mm = 0, dr_y_mm = 0;
  double dP_axial_max_D = 0;  // max |P - P_truth| over the compared disc
  double dP_tangential_max_D = 0;
  double dpv_axial_D = 0;  // pv(P) - pv(P_truth) over the whole map disc (paper Table VII's measure)
  double dpv_tangential_D = 0;
  double compared_radius_mm = 0;  // radius of the compared disc: where both reconstructions have points

  double MaxAbsDk() const;
  double MaxAbsDP_D(const HarnessLimits& limits) const;  // the maps the limits name
};

// The truth reconstruction of one cornea.
struct HarnessTruth {
  std::string cornea;
  model::BiconicParams fit;  // biconic fitted to the truth reconstruction
  double covered_radius_mm = 0;
  double spot_field_radius_mm = 0;  // largest distance of an undistorted spot from the distortion centre
  int spots = 0;
  double pv_axial_D = 0, pv_tangential_D = 0;
};

// Every case of the configuration in the fixed global order.
std::vector<HarnessCaseSpec> EnumerateHarnessCases(const HarnessConfig& config);
// The cases of one shard (index % N == i), in the same order; *total is the number of cases of all shards.
std::vector<HarnessCaseSpec> EnumerateHarnessCases(const HarnessConfig& config, util::ShardSpec shard, int* total);
// The seed of case `index`: SplitMix64 of (config seed, index).
std::uint64_t HarnessCaseSeed(std::uint64_t config_seed, int index);

// The nominal device of the harness: the design's a, the configuration's pixel pitch, no distortion, the screen where
// the design puts it (the principal point, sensor size and orientation of model::TopographerCamera's defaults:
// measuring through this device undoes its pixel mapping exactly).
model::Device HarnessNominalDevice(const HarnessConfig& config);
// The as-built device of an assembly case: the nominal device with the case's one error.
model::Device AssembledDevice(const HarnessConfig& config, const HarnessCaseSpec& spec);

// The cases of one shard (or of all: shard 0/1) and the truth reconstructions.
struct HarnessRun {
  HarnessConfig config;
  std::string config_sha256;
  util::ShardSpec shard;
  int total_cases = 0;
  std::vector<HarnessTruth> truth;       // one per cornea
  std::vector<HarnessCaseResult> cases;  // sorted by index
};

// Runs the shard's cases on `jobs` threads (results do not depend on jobs). Throws std::runtime_error when a truth
// reconstruction fails (the design cannot reconstruct that cornea at all).
// `progress`, when given, is called from the worker threads after each case with (cases done, cases of the shard).
HarnessRun RunHarness(const HarnessConfig& config, util::ShardSpec shard, int jobs = 1,
                      const std::function<void(std::size_t, std::size_t)>& progress = {});

// Runs one case against its truth (exposed for tests and the benchmark).
class HarnessCaseRunner {
 public:
  explicit HarnessCaseRunner(const HarnessConfig& config);  // designs the screen, reconstructs every truth
  HarnessCaseResult Run(const HarnessCaseSpec& spec) const;
  const std::vector<HarnessTruth>& truth() const { return truth_; }

 private:
  struct CorneaData;
  HarnessCaseResult RunDistortion(const HarnessCaseSpec& spec) const;
  HarnessCaseResult RunAssembly(const HarnessCaseSpec& spec) const;
  // Fills the errors of `r` from the analysis of its measured spots against the truth of its cornea.
  static void Compare(const topo::Analysis& analysis, const CorneaData& d, HarnessCaseResult* r);
  HarnessConfig config_;  // a copy: the runner may outlive the caller's configuration
  std::shared_ptr<const std::vector<model::TargetPoint>> targets_;
  model::Device nominal_;
  std::vector<HarnessTruth> truth_;
  std::vector<std::shared_ptr<const CorneaData>> data_;
};

// A shard as a JSON file and back. Reading checks the format and every field; throws util::InputError naming the
// file and key. The cases are one array per line under "case_columns" (docs/harness.md): a shard's size and reading
// time grow with its cases, ~265 bytes each.
std::string HarnessShardJson(const HarnessRun& run);
// The truth reconstructions as the shard and the report's JSON both write them.
nlohmann::json HarnessTruthJson(const std::vector<HarnessTruth>& truth);
HarnessRun ParseHarnessShard(const std::string& json_text, const std::string& origin);
// The shard files one `harness merge` argument names: the file itself, or the shard-*.json files of a directory,
// sorted. Throws util::InputError naming the argument when it does not exist, cannot be listed or holds no shard.
std::vector<std::string> ShardFilesIn(const std::string& path);
// The file name a shard is written under: "shard-<i>-of-<N>.json".
std::string HarnessShardFileName(util::ShardSpec shard);

// Combines shards into the run of all cases. Throws util::InputError when the shards come from different
// configurations or tool versions, when one is missing or given twice, or when a case is missing or duplicated.
HarnessRun MergeHarnessShards(const std::vector<HarnessRun>& shards, const std::vector<std::string>& origins);

// The same merge one shard at a time, for many or large shards: each shard's cases move into the merged run as it
// is added (memory: the merged cases and one shard), and the cases of the configuration are enumerated once, not
// once per shard file. Add() throws as MergeHarnessShards does, as soon as a shard does not belong; Finish() when a
// shard or a case is missing.
class HarnessShardMerger {
 public:
  void Add(const std::string& json_text, const std::string& origin);  // a shard file's text
  void Add(HarnessRun shard, const std::string& origin);
  HarnessRun Finish();

 private:
  HarnessRun merged_;  // config, truth and the cases filled so far (shard: the first shard's split)
  std::string first_origin_;
  std::vector<HarnessCaseSpec> all_;   // every case of the first shard's configuration (read from text)
  std::map<int, std::string> shards_;  // shard index -> the file it came from
  std::vector<bool> filled_;           // per case
};

}  // namespace topocal::harness

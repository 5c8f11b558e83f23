#include "report/sweep_command.h"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <optional>
#include <stdexcept>

#include "model/device.h"
#include "report/analysis_json.h"
#include "util/new_directory_guard.h"

namespace topocal::report {
namespace {

void PrintTableVI(std::ostream& out, const topo::SweepResult& r) {
  const char* mode = r.rows.empty() ? "" : topo::BiconicFitModeName(r.rows[0].analysis.surface_fit.mode);
  fmt::print(out, "\nTable VI — biconic fitted to the reconstructed surface (rx >= ry, alpha in [0, 180); {} fit)\n",
             mode);
  fmt::print(out, "{:>12}  {:>8}  {:>8}  {:>8}  {:>8}  {:>9}  {:>10}  {:>9}  {:>8}\n", "sigma/mm^2", "rx/mm", "ry/mm", "kx",
             "ky", "alpha/deg", "vertex/um", "apex/mm", "tilt/deg");
  for (const auto& row : r.rows) {
    const auto& f = row.analysis.surface_fit;
    const auto& p = f.params;
    fmt::print(out, "{:>12.3g}  {:>8.4f}  {:>8.4f}  {:>8.4f}  {:>8.4f}  {:>9.4f}  {:>10.4f}  {:>9.5f}  {:>8.4f}\n",
               row.sigma_per_mm2, p.rx_mm, p.ry_mm, p.kx, p.ky, p.alpha_deg, p.z0_mm * 1e3, f.DecentrationMm(),
               f.TiltDeg());
  }
}

void PrintClinical(std::ostream& out, const topo::SweepResult& r) {
  fmt::print(out, "\nModel adequacy and clinical indices (within the supported radius: data in every direction)\n");
  fmt::print(out, "{:>12}  {:>9}  {:>8}  {:>9}  {:>9}  {:>8}  {:>8}  {:>9}  {:>7}\n", "sigma/mm^2", "adequacy", "support",
             "steepK/D", "flatK/D", "axis/deg", "Kmax/D", "elev/um", "I-S/D");
  for (const auto& row : r.rows) {
    const auto& a = row.analysis;
    const auto& c = a.clinical;
    fmt::print(out, "{:>12.3g}  {:>9.3g}  {:>8.2f}  {:>9.3f}  {:>9.3f}  {:>8.1f}  {:>8.3f}  {:>9.3f}  {:>7.3f}{}\n",
               row.sigma_per_mm2, a.reconstruction.adequacy_ratio, a.supported_radius_mm, c.steep_k_D, c.flat_k_D,
               c.steep_axis_deg, c.kmax_D, c.elevation_peak_um, c.inferior_superior_D,
               topo::ModelFitsData(a.reconstruction) ? "" : "  model does not fit");
  }
}

void PrintTableVII(std::ostream& out, const topo::SweepResult& r) {
  fmt::print(out, "\nTable VII — height difference to the true cornea and power-map peak-to-valley (R = {:.2f} mm)\n",
             r.ideal_power.radius_mm);
  fmt::print(out, "{:>12}  {:>10}  {:>10}  {:>10}  {:>10}\n", "sigma/mm^2", "pv/um", "rms/um", "pv_m/D", "pv_a/D");
  for (const auto& row : r.rows) {
    const auto& a = row.analysis;
    fmt::print(out, "{:>12.3g}  {:>10.4f}  {:>10.4f}  {:>10.3f}  {:>10.3f}\n", row.sigma_per_mm2,
               a.errors ? a.errors->pv_um : 0.0, a.errors ? a.errors->rms_um : 0.0, a.power.pv_tangential_D,
               a.power.pv_axial_D);
  }
  fmt::print(out, "{:>12}  {:>10}  {:>10}  {:>10.3f}  {:>10.3f}\n", "ideal", "", "", r.ideal_power.pv_tangential_D,
             r.ideal_power.pv_axial_D);
}

// The calibrated unit's answer beside the rows (the unit uncalibrated, assembly and sigma left in).
void PrintThroughDevice(std::ostream& out, const topo::SweepResult& r, const std::string& device_path) {
  if (!r.through_device) return;
  const auto& a = *r.through_device;
  const auto& f = a.surface_fit;
  const auto& p = f.params;
  fmt::print(out, "\nThrough the device {} with its geometry and the sigma known (the calibrated unit; the rows above "
             "are the unit uncalibrated)\n", device_path);
  fmt::print(out, "{:>8}  {:>8}  {:>8}  {:>8}  {:>9}  {:>10}  {:>9}  {:>8}  {:>10}  {:>10}\n", "rx/mm", "ry/mm", "kx", "ky",
             "alpha/deg", "vertex/um", "apex/mm", "tilt/deg", "pv_m/D", "pv_a/D");
  fmt::print(out, "{:>8.4f}  {:>8.4f}  {:>8.4f}  {:>8.4f}  {:>9.4f}  {:>10.4f}  {:>9.5f}  {:>8.4f}  {:>10.3f}  {:>10.3f}\n",
             p.rx_mm, p.ry_mm, p.kx, p.ky, p.alpha_deg, p.z0_mm * 1e3, f.DecentrationMm(), f.TiltDeg(),
             a.power.pv_tangential_D, a.power.pv_axial_D);
}

void PrintCorrection(std::ostream& out, const topo::SweepResult& r,
                     const std::vector<pipeline::ClosedLoopResult>& corrected) {
  fmt::print(out, "\nBefore / after correction — single-view Seidel calibration at the cornea position, spots "
             "detected in the rendered sensor image, undistorted, reconstructed\n");
  fmt::print(out, "{:>10} {:>11} {:>7} | {:>16} {:>16} {:>16} {:>16} | {:>17} {:>15} {:>15}\n", "sigma", "sigma_est",
             "rms_px", "kx before>after", "ky before>after", "rx before>after", "ry before>after",
             "pv_um before>after", "pv_m before>after", "pv_a before>after");
  for (size_t i = 0; i < corrected.size(); ++i) {
    const auto& b = r.rows[i].analysis;
    const auto& c = corrected[i];
    const auto& a = c.corrected;
    const auto& pb = b.surface_fit.params;
    const auto& pa = a.surface_fit.params;
    fmt::print(out, "{:>10.3g} {:>11.4g} {:>7.3f} | {:>7.4f} > {:>6.4f} {:>7.4f} > {:>6.4f} {:>7.4f} > {:>6.4f} "
               "{:>7.4f} > {:>6.4f} | {:>8.3f} > {:>6.3f} {:>6.2f} > {:>6.2f} {:>6.2f} > {:>6.2f}\n",
               r.rows[i].sigma_per_mm2, c.calibration.sigma_estimated_per_mm2, c.calibration.residual_rms_px, pb.kx,
               pa.kx, pb.ky, pa.ky, pb.rx_mm, pa.rx_mm, pb.ry_mm, pa.ry_mm, b.errors ? b.errors->pv_um : 0.0,
               a.errors ? a.errors->pv_um : 0.0, b.power.pv_tangential_D, a.power.pv_tangential_D,
               b.power.pv_axial_D, a.power.pv_axial_D);
  }
}

void PrintTableV(std::ostream& out, const topo::SweepResult& r) {
  fmt::print(out, "Table V — image contour (Fitzgibbon fit to the outer ring), {} spots\n", r.spots);
  fmt::print(out, "{:>12}  {:>9}  {:>9}  {:>9}  {:>10}  {:>8}\n", "sigma/mm^2", "a_e/mm", "b_e/mm", "beta_e/deg",
             "area/mm^2", "E_A/%");
  for (const auto& row : r.rows) {
    fmt::print(out, "{:>12.3g}  {:>9.4f}  {:>9.4f}  {:>9.4f}  {:>10.4f}  {:>8.2f}\n", row.sigma_per_mm2,
               row.image_ellipse.a_mm, row.image_ellipse.b_mm, row.image_ellipse.beta_deg, row.image_ellipse.AreaMm2(),
               row.area_change_pct);
  }
}

}  // namespace

void RunSweep(const SweepRequest& a, std::ostream& out) {
  const util::NewDirectoryGuard maps_guard(a.maps);  // a failed run leaves no empty --maps folder
  if ((a.correct || !a.maps.empty()) && !a.image_stages) {
    throw std::logic_error("sweep: --correct and --maps need the image stages (OpenCV)");
  }
  auto cfg = model::LoadConfig(a.config);
  if (a.adjust_config) a.adjust_config(&cfg);
  if (!a.device.empty() && a.correct) {
    throw util::InputError("--device: not with --correct (the closed loop calibrates a rendered camera, not a device)");
  }
  std::optional<model::Device> as_built;
  if (!a.device.empty()) as_built = model::LoadDevice(a.device).device;
  // The closed loop's camera: the paper's sensor (model/paper_topographer.h), a from the configuration.
  pipeline::ClosedLoopOptions options;
  options.camera.a_mm = cfg.topographer.a_mm;
  const auto result = topo::RunSweep(cfg, 0, as_built ? &*as_built : nullptr);
  for (const auto& f : result.synthesis_failures) {
    util::Log(a.log, fmt::format("spot ({}, {}) not imaged: {}", f.id.ring, f.id.index, f.reason));
  }
  PrintTableV(out, result);
  PrintTableVI(out, result);
  PrintThroughDevice(out, result, a.device);
  PrintTableVII(out, result);
  PrintClinical(out, result);
  std::vector<pipeline::ClosedLoopResult> corrected;
  if (a.correct) {
    corrected = a.image_stages->close_loops(cfg, result, options, a.log);
    PrintCorrection(out, result, corrected);
  }
  util::StagedOutputs outputs;  // the JSON and the maps are published together or not at all
  if (!a.json.empty()) outputs.AddFile(a.json, SweepJson(result, corrected));
  if (!a.maps.empty()) a.image_stages->write_maps(outputs, a.maps, cfg, result);
  outputs.Commit();
}

}  // namespace topocal::report

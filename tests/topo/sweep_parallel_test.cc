#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "model/config.h"
#include "topo/sweep.h"

namespace topocal::topo {
namespace {

// Every number of a sweep row, in one list, so that two sweeps compare with == (bit for bit).
std::vector<double> Numbers(const SweepRow& row) {
  const Analysis& a = row.analysis;
  std::vector<double> v = {row.sigma_per_mm2, row.image_ellipse.AreaMm2(), row.image_ellipse.beta_deg,
                           row.area_change_pct, static_cast<double>(row.spots_imaged)};
  const Reconstruction& r = a.reconstruction;
  for (int k = 0; k < r.surface.terms(); ++k) v.push_back(r.surface.coefficients()(k));
  for (const auto& p : r.points) {
    v.insert(v.end(), {p.point_mm.x(), p.point_mm.y(), p.point_mm.z(), p.normal.x(), p.normal.y(), p.zonal_z_mm});
  }
  v.insert(v.end(), {r.vertex_t_mm, r.consistency, r.rms_slope_residual, r.expected_slope_noise, r.adequacy_ratio,
                     r.residual_neighbour_correlation, r.structured_residual_ratio, static_cast<double>(r.iterations)});
  const auto& f = a.surface_fit;
  v.insert(v.end(), {f.params.rx_mm, f.params.ry_mm, f.params.kx, f.params.ky, f.params.alpha_deg, f.params.z0_mm,
                     f.params.x0_mm, f.params.y0_mm, f.params.tilt_x_deg, f.params.tilt_y_deg, f.stddev.rx_mm,
                     f.stddev.kx, f.stddev.alpha_deg, f.rms_residual_um, static_cast<double>(f.iterations)});
  v.insert(v.end(), a.power.axial_D.begin(), a.power.axial_D.end());
  v.insert(v.end(), a.power.tangential_D.begin(), a.power.tangential_D.end());
  v.insert(v.end(), {a.power.pv_axial_D, a.power.pv_tangential_D, a.covered_radius_mm, a.supported_radius_mm,
                     a.clinical.steep_k_D, a.clinical.flat_k_D, a.clinical.kmax_D, a.clinical.bfs_radius_mm,
                     a.clinical.elevation_peak_um, a.clinical.inferior_superior_D});
  if (a.errors) v.insert(v.end(), {a.errors->pv_um, a.errors->rms_um});
  return v;
}

// The sigmas of the sweep run in parallel; the rows must not depend on the thread count or on which
// thread ran which sigma (each sigma writes only its own row).
TEST(Sweep, RowsAreBitIdenticalWhateverTheThreadCount) {
  const auto config = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  const SweepResult serial = RunSweep(config, 1);
  ASSERT_EQ(serial.rows.size(), config.distortion.sigmas_per_mm2.size());
  for (const int jobs : {2, 3, 16}) {
    const SweepResult parallel = RunSweep(config, jobs);
    ASSERT_EQ(parallel.rows.size(), serial.rows.size()) << jobs << " threads";
    for (size_t i = 0; i < serial.rows.size(); ++i) {
      const auto a = Numbers(serial.rows[i]), b = Numbers(parallel.rows[i]);
      ASSERT_EQ(a.size(), b.size());
      for (size_t k = 0; k < a.size(); ++k) {
        ASSERT_EQ(a[k], b[k]) << jobs << " threads, sigma " << serial.rows[i].sigma_per_mm2 << ", number " << k;
      }
      EXPECT_EQ(serial.rows[i].analysis.warnings, parallel.rows[i].analysis.warnings);
    }
    EXPECT_EQ(serial.ideal_power.axial_D, parallel.ideal_power.axial_D) << jobs << " threads";
    EXPECT_EQ(serial.ideal_power.tangential_D, parallel.ideal_power.tangential_D) << jobs << " threads";
  }
}

}  // namespace
}  // namespace topocal::topo

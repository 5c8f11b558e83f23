#include "tools/report_json.h"

namespace topocal::tools {

nlohmann::json SurfaceFitJson(const topo::BiconicFit& f) {
  const auto& p = f.params;
  const auto& sd = f.stddev;
  nlohmann::json j = {{"rx_mm", p.rx_mm},     {"ry_mm", p.ry_mm},         {"kx", p.kx},
                      {"ky", p.ky},           {"alpha_deg", p.alpha_deg}, {"vertex_um", p.z0_mm * 1e3},
                      {"rms_um", f.rms_residual_um}};
  if (f.stddev_ok) {
    j["stddev"] = {{"rx_mm", sd.rx_mm}, {"ry_mm", sd.ry_mm},         {"kx", sd.kx},
                   {"ky", sd.ky},       {"alpha_deg", sd.alpha_deg}, {"vertex_um", sd.z0_mm * 1e3}};
  }
  return j;
}

nlohmann::json ReconstructionJson(const topo::Reconstruction& r) {
  nlohmann::json unmatched = nlohmann::json::array();
  for (const auto& id : r.unmatched) unmatched.push_back({id.ring, id.index});
  return {{"method", r.method},
          {"spots_used", r.spots_used},
          {"unmatched", unmatched},
          {"vertex_t_um", r.vertex_t_mm * 1e3},
          {"iterations", r.iterations},
          {"consistency_delta", r.consistency},
          {"rms_slope_residual", r.rms_slope_residual}};
}

nlohmann::json ErrorsJson(const topo::Analysis& a) {
  nlohmann::json j = {{"pv_tangential_D", a.power.pv_tangential_D},
                      {"pv_axial_D", a.power.pv_axial_D},
                      {"map_radius_mm", a.power.radius_mm},
                      {"covered_radius_mm", a.covered_radius_mm}};
  if (a.errors) {
    j["pv_um"] = a.errors->pv_um;
    j["rms_um"] = a.errors->rms_um;
  }
  return j;
}

nlohmann::json PolynomialJson(const topo::TaylorPolynomial& p) {
  nlohmann::json terms = nlohmann::json::array();
  for (int k = 0; k < p.terms(); ++k) {
    const auto [a, b] = p.Exponents(k);
    terms.push_back({{"u_power", a}, {"v_power", b}, {"coefficient_mm", p.coefficients()(k)}});
  }
  return {{"degree", p.degree()},
          {"terms", p.terms()},
          {"norm_radius_mm", p.norm_radius_mm()},
          {"definition", "Psi(x,y) = sum coefficient_mm * (x/R)^u_power * (y/R)^v_power, R = norm_radius_mm"},
          {"coefficients", terms}};
}

}  // namespace topocal::tools

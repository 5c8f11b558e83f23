#include "report/analysis_json.h"

#include <algorithm>
#include <cmath>

#include "pipeline/uncertainty.h"
#include "topo/power_map.h"
#include "util/json_section.h"

namespace topocal::report {

nlohmann::json SurfaceFitJson(const topo::BiconicFit& f) {
  const auto& p = f.params;
  const auto& sd = f.stddev;
  nlohmann::json j = {{"rx_mm", p.rx_mm},     {"ry_mm", p.ry_mm},         {"kx", p.kx},
                      {"ky", p.ky},           {"alpha_deg", p.alpha_deg}, {"vertex_um", p.z0_mm * 1e3},
                      {"rms_um", f.rms_residual_um}, {"mode", topo::BiconicFitModeName(f.mode)},
                      {"apex_x_mm", f.apex_mm.x()}, {"apex_y_mm", f.apex_mm.y()},
                      {"decentration_mm", f.DecentrationMm()}, {"tilt_x_deg", p.tilt_x_deg},
                      {"tilt_y_deg", p.tilt_y_deg}, {"tilt_deg", f.TiltDeg()}};
  if (f.stddev_ok) {
    j["stddev"] = {{"rx_mm", sd.rx_mm}, {"ry_mm", sd.ry_mm},         {"kx", sd.kx},
                   {"ky", sd.ky},       {"alpha_deg", sd.alpha_deg}, {"vertex_um", sd.z0_mm * 1e3},
                   {"apex_x_mm", sd.apex_x_mm}, {"apex_y_mm", sd.apex_y_mm},
                   {"tilt_x_deg", sd.tilt_x_deg}, {"tilt_y_deg", sd.tilt_y_deg}};
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

nlohmann::json ClinicalJson(const topo::Analysis& a) {
  if (!a.clinical_ok) return {{"error", a.clinical_message}};
  const auto& c = a.clinical;
  nlohmann::json j = {
      {"supported_radius_mm", c.supported_radius_mm},
      {"sim_k", {{"steep_D", c.steep_k_D}, {"steep_axis_deg", c.steep_axis_deg}, {"flat_D", c.flat_k_D},
                 {"flat_axis_deg", c.flat_axis_deg}, {"cylinder_D", c.CylinderD()}}},
      {"kmax", {{"power_D", c.kmax_D}, {"x_mm", c.kmax_at_mm.x()}, {"y_mm", c.kmax_at_mm.y()}}},
      {"best_fit_sphere", {{"radius_mm", c.bfs_radius_mm}, {"zone_radius_mm", c.bfs_zone_radius_mm},
                           {"centre_mm", {c.bfs_centre_mm.x(), c.bfs_centre_mm.y(), c.bfs_centre_mm.z()}},
                           {"elevation_peak_um", c.elevation_peak_um},
                           {"elevation_peak_x_mm", c.elevation_peak_at_mm.x()},
                           {"elevation_peak_y_mm", c.elevation_peak_at_mm.y()},
                           {"elevation_rms_um", c.elevation_rms_um}}}};
  if (c.is_available) {
    j["inferior_superior_D"] = c.inferior_superior_D;
  } else {
    j["inferior_superior_D"] = nullptr;
  }
  return j;
}

nlohmann::json AdequacyJson(const topo::Analysis& a) {
  const auto& r = a.reconstruction;
  return {{"rms_slope_residual", r.rms_slope_residual},
          {"expected_slope_noise", r.expected_slope_noise},
          {"ratio", r.adequacy_ratio},
          {"warning_ratio", topo::kAdequacyWarningRatio},
          {"residual_neighbour_correlation", r.residual_neighbour_correlation},
          {"structured_residual_ratio", r.structured_residual_ratio},
          {"structured_warning_ratio", topo::kStructuredResidualWarningRatio},
          {"model_fits_data", topo::ModelFitsData(r)},
          {"surface_model", r.surface_model},
          {"surface_model_reason", r.surface_model_reason},
          {"covered_radius_mm", a.covered_radius_mm},
          {"supported_radius_mm", a.supported_radius_mm},
          {"map_radius_mm", a.power.radius_mm},
          {"maps_extrapolated", a.maps_extrapolated},
          {"warnings", a.warnings}};
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

std::string SweepJson(const topo::SweepResult& r, const std::vector<pipeline::ClosedLoopResult>& corrected) {
  nlohmann::json j;
  j["spots"] = r.spots;
  j["rows"] = nlohmann::json::array();
  for (const auto& row : r.rows) {
    nlohmann::json jr;
    jr["sigma_per_mm2"] = row.sigma_per_mm2;
    jr["spots_imaged"] = row.spots_imaged;
    jr["image_ellipse"] = {{"a_mm", row.image_ellipse.a_mm},
                           {"b_mm", row.image_ellipse.b_mm},
                           {"beta_deg", row.image_ellipse.beta_deg},
                           {"area_mm2", row.image_ellipse.AreaMm2()},
                           {"area_change_pct", row.area_change_pct}};
    const auto& a = row.analysis;
    jr["surface_fit"] = report::SurfaceFitJson(a.surface_fit);
    jr["reconstruction"] = report::ReconstructionJson(a.reconstruction);
    jr["errors"] = report::ErrorsJson(a);
    jr["clinical"] = report::ClinicalJson(a);
    jr["adequacy"] = report::AdequacyJson(a);
    const size_t i = j["rows"].size();
    if (i < corrected.size()) {
      const auto& c = corrected[i];
      jr["corrected"] = {{"surface_fit", report::SurfaceFitJson(c.corrected.surface_fit)},
                         {"errors", report::ErrorsJson(c.corrected)},
                         {"reconstruction", report::ReconstructionJson(c.corrected.reconstruction)},
                         {"spots_indexed", c.spots_indexed},
                         {"spots_unassigned", c.spots_unassigned},
                         {"spots_missing", c.spots_missing}};
      jr["calibration"] = {{"sigma_estimated_per_mm2", c.calibration.sigma_estimated_per_mm2},
                           {"sigma_stddev_per_mm2", c.calibration.sigma_stddev_per_mm2},
                           {"residual_rms_px", c.calibration.residual_rms_px},
                           {"corners", c.calibration.corners}};
    }
    j["rows"].push_back(jr);
  }
  j["ideal"] = {{"pv_tangential_D", r.ideal_power.pv_tangential_D}, {"pv_axial_D", r.ideal_power.pv_axial_D}};
  j["timing_ms"] = {{"design", r.timing.design_ms},
                    {"synthesis", r.timing.synthesis_ms},
                    {"analysis", r.timing.analysis_ms},
                    {"total", r.timing.total_ms}};
  if (r.through_device) {
    // The calibrated unit's answer (the rows are the unit uncalibrated); absent without a device.
    j["through_device"] = {{"surface_fit", report::SurfaceFitJson(r.through_device->surface_fit)},
                           {"errors", report::ErrorsJson(*r.through_device)},
                           {"clinical", report::ClinicalJson(*r.through_device)}};
  }
  return util::JsonFileText(j);
}

nlohmann::json CaptureJson(const pipeline::CaptureQuality& q) {
  return {{"designed", q.designed},
          {"identified", q.identified},
          {"usable", q.usable},
          {"refused_identities", q.refused},
          {"unidentified_blobs", q.unassigned},
          {"visible_fraction", q.visible_fraction},
          {"largest_gap_deg", q.largest_gap_deg},
          {"gap_side", q.gap_side},
          {"median_spot_area_px", q.median_spot_area_px},
          {"surface_outliers", q.surface_outliers.size()},
          {"surface_labelled", q.surface_labelled}};
}

nlohmann::json DetectionJson(const correct::DetectAndIndexResult& r, correct::CentroidMethod estimator,
                             const pipeline::CaptureQuality& capture) {
  nlohmann::json j;
  j["estimator"] = correct::CentroidMethodName(estimator);
  j["indexed"] = r.spots.size() + r.excluded.size();
  j["excluded"] = r.excluded.size();
  j["unassigned"] = r.unassigned.size();
  j["missing"] = nlohmann::json::array();
  for (const auto& m : r.missing) j["missing"].push_back({m.ring, m.index});
  j["noise_model"] = {{"background_dn", r.detection.background_dn},
                      {"read_noise_dn", r.detection.read_noise_dn},
                      {"read_noise", r.detection.read_noise_source},
                      {"gain_e_per_dn", r.detection.gain_e_per_dn},
                      {"gain", r.detection.gain_source}};
  j["orientation"] = r.orientation.message;
  j["capture"] = CaptureJson(capture);
  return j;
}

nlohmann::json MeasurementJson(const topo::Analysis& a, bool truth) {
  nlohmann::json j;
  j["reconstruction"] = ReconstructionJson(a.reconstruction);
  j["polynomial"] = PolynomialJson(a.reconstruction.surface);
  j["surface_fit"] = SurfaceFitJson(a.surface_fit);
  const double central = topo::MeanAxialPowerD(a.power, pipeline::kCentralPowerRadiusMm);
  j["power"] = {{"pv_tangential_D", a.power.pv_tangential_D}, {"pv_axial_D", a.power.pv_axial_D},
                {"central_axial_D", std::isfinite(central) ? nlohmann::json(central) : nlohmann::json(nullptr)},
                {"central_radius_mm", pipeline::kCentralPowerRadiusMm},
                {"map_radius_mm", a.power.radius_mm}, {"covered_radius_mm", a.covered_radius_mm}};
  if (truth) j["errors"] = ErrorsJson(a);
  j["clinical"] = ClinicalJson(a);
  j["adequacy"] = AdequacyJson(a);
  return j;
}

void WithdrawUndetermined(const pipeline::MeasurementUncertainty& u, nlohmann::json* measurement) {
  for (const auto& q : u.quantities) {
    if (q.determined) continue;
    std::string pointer = "/" + q.name;
    std::replace(pointer.begin(), pointer.end(), '.', '/');
    const nlohmann::json::json_pointer at(pointer);
    if (measurement->contains(at)) (*measurement)[at] = nullptr;
  }
}

nlohmann::json MeasurementUncertaintyJson(const pipeline::MeasurementUncertainty& u) {
  nlohmann::json quantities = nlohmann::json::object();
  for (const auto& q : u.quantities) {
    quantities[q.name] = {{"value", q.value},
                          {"expanded", q.determined ? nlohmann::json(q.expanded) : nlohmann::json(nullptr)},
                          {"determined", q.determined},
                          {"lower_bound", q.lower_bound},
                          {"unit", q.unit},
                          {"u_device", q.u_device}, {"u_spots", q.u_spots},   {"u_bias", q.u_bias},
                          {"u_resolution", q.u_resolution}};
  }
  double max_axial_u = 0;
  for (const double x : u.axial_expanded_D) max_axial_u = std::max(max_axial_u, x);
  return {{"coverage_factor", 2},
          {"method", u.device_monte_carlo ? "device: Monte Carlo; spots: Monte Carlo" : "device: linear; spots: Monte Carlo"},
          {"device_covariance", u.device_covariance},
          {"device_parameters", u.device_parameters},
          {"device_directions", u.device_directions},
          {"device_analyses", u.device_analyses},
          {"configured_spot_sigma_um", u.configured_spot_sigma_um},
          {"measured_spot_sigma_um", u.spot_sigma_um},
          {"spot_draws", u.spot_draws},
          {"failed_analyses", u.failed_draws},
          {"axial_map_max_expanded_D", max_axial_u},
          {"supported_disc_rms_expanded_D", u.axial_rms_expanded_D},
          {"supported_disc_max_expanded_D", u.axial_max_expanded_D},
          {"quantities", quantities}};
}

}  // namespace topocal::report

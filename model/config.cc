#include "model/config.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "model/distortion.h"
#include "model/null_screen.h"
#include "model/surface.h"
#include "util/io.h"
#include "util/json_section.h"

namespace topocal::model {
namespace {

using nlohmann::json;

using Section = util::JsonSection;

// The largest null-screen design a configuration may ask for: 160 times the paper's 624 spots, far denser than a
// sensor resolves (the denser screens of docs/reconstruction.md stay well below it), small enough to design in well
// under a second.
constexpr std::int64_t kMaxNullScreenSpots = 100'000;

void ParseIdealImage(Section s, IdealImageParams& p) {
  p.rho0_mm = s.Number("rho0_mm");
  p.rhoN_mm = s.Number("rhoN_mm");
  p.rings_N = s.Integer("rings_N");
  p.eta0 = s.Integer("eta0");
  p.eta = s.Integer("eta");
  p.spot_radius_um = s.Number("spot_radius_um", p.spot_radius_um);
  if (s.Has("orientation_key")) {
    const json& v = s.Get("orientation_key");
    if (!v.is_boolean()) s.Fail(s.Key("orientation_key"), "must be true or false");
    p.orientation_key = v.get<bool>();
  }
  s.Positive("rho0_mm", p.rho0_mm);
  s.Positive("rhoN_mm", p.rhoN_mm);
  if (p.rhoN_mm <= p.rho0_mm) s.Fail(s.Key("rhoN_mm"), fmt::format("must exceed rho0_mm (got {} <= {})", p.rhoN_mm, p.rho0_mm));
  // rings_N = N: N + 1 rings; N >= 1 keeps Eq. 2a's step (rhoN - rho0)/N defined, i.e. at least two rings.
  s.AtLeast("rings_N", p.rings_N, 1);
  s.AtLeast("eta0", p.eta0, 1);
  s.AtLeast("eta", p.eta, 0);
  s.Positive("spot_radius_um", p.spot_radius_um);
  // The spot count is the design's size: every spot is traced, imaged, indexed and fitted. Counted in 64 bits
  // before any allocation (the fuzzer found rings_N = 7297 with eta = 8: 2e8 spots, 23 GB, then bad_alloc).
  const std::int64_t n = p.rings_N, spots = (n + 1) * p.eta0 + std::int64_t{p.eta} * n * (n + 1) / 2;
  if (spots > kMaxNullScreenSpots) {
    s.Fail(s.Key("rings_N"), fmt::format("rings_N = {}, eta0 = {}, eta = {} give {} spots; a null screen has at most {} "
                                         "(the paper's has 624)",
                                         p.rings_N, p.eta0, p.eta, spots, kMaxNullScreenSpots));
  }
  // The key's three spots sit on three different rings (model::OrientationKeySpots).
  if (p.orientation_key && p.rings_N < 4) s.Fail(s.Key("orientation_key"), "needs rings_N >= 4 (three distinct key rings)");
  s.RejectUnknown();
}

void ParseTopographer(Section s, TopographerParams& p) {
  p.a_mm = s.Number("a_mm");
  p.b_mm = s.Number("b_mm");
  p.re_mm = s.Number("re_mm");
  p.cone_semi_angle_deg = s.Number("cone_semi_angle_deg");
  p.cone_vertex_z_mm = s.Number("cone_vertex_z_mm");
  s.Positive("a_mm", p.a_mm);
  s.Positive("b_mm", p.b_mm);
  s.Positive("re_mm", p.re_mm);
  if (!(p.cone_semi_angle_deg > 0 && p.cone_semi_angle_deg < 90)) {
    s.Fail(s.Key("cone_semi_angle_deg"), fmt::format("must lie in (0, 90) degrees (got {})", p.cone_semi_angle_deg));
  }
  // The cone must open towards the eye from behind the pinhole, or the camera sits outside it.
  if (!(p.cone_vertex_z_mm < -p.b_mm)) {
    s.Fail(s.Key("cone_vertex_z_mm"),
           fmt::format("must lie behind the pinhole, below -b_mm = {} (got {}; see docs/paper-decisions.md)", -p.b_mm,
                       p.cone_vertex_z_mm));
  }
  s.RejectUnknown();
}

void ParseCornea(Section s, BiconicParams& p) {
  p.rx_mm = s.Number("rx_mm");
  p.ry_mm = s.Number("ry_mm");
  p.kx = s.Number("kx");
  p.ky = s.Number("ky");
  p.alpha_deg = s.Number("alpha_deg");
  p.x0_mm = s.Number("x0_mm", 0.0);
  p.y0_mm = s.Number("y0_mm", 0.0);
  p.z0_mm = s.Number("z0_mm", 0.0);
  p.tilt_x_deg = s.Number("tilt_x_deg", 0.0);
  p.tilt_y_deg = s.Number("tilt_y_deg", 0.0);
  s.Positive("rx_mm", p.rx_mm);
  // The tilted sag is solved by Newton from the untilted one (model/surface.h); beyond ~30 deg the cap folds over.
  if (std::abs(p.tilt_x_deg) > 30.0) s.Fail(s.Key("tilt_x_deg"), fmt::format("must lie in [-30, 30] (got {})", p.tilt_x_deg));
  if (std::abs(p.tilt_y_deg) > 30.0) s.Fail(s.Key("tilt_y_deg"), fmt::format("must lie in [-30, 30] (got {})", p.tilt_y_deg));
  s.Positive("ry_mm", p.ry_mm);
  s.RejectUnknown();
}

void ParseDistortion(Section s, DistortionSweep& p) {
  p.model = s.String("model");
  if (p.model != "seidel") s.Fail(s.Key("model"), fmt::format("must be \"seidel\" (got \"{}\")", p.model));
  p.magnification = s.Number("MT");
  if (p.magnification == 0) s.Fail(s.Key("MT"), "must be non-zero");
  p.centre_x_mm = s.Number("centre_x_mm", 0.0);
  p.centre_y_mm = s.Number("centre_y_mm", 0.0);
  const json& sig = s.Get("sigmas_per_mm2");
  if (!sig.is_array()) s.Fail(s.Key("sigmas_per_mm2"), "must be an array of numbers");
  if (sig.empty()) s.Fail(s.Key("sigmas_per_mm2"), "must not be empty");
  p.sigmas_per_mm2.clear();
  for (size_t i = 0; i < sig.size(); ++i) {
    if (!sig[i].is_number() || !std::isfinite(sig[i].get<double>())) {
      s.Fail(fmt::format("{}[{}]", s.Key("sigmas_per_mm2"), i),
             fmt::format("must be a finite number (got {})", util::QuoteJsonValue(sig[i])));
    }
    p.sigmas_per_mm2.push_back(sig[i].get<double>());
  }
  s.RejectUnknown();
}

// After ideal_image and distortion are read: every sigma must leave the image unfolded.
void CheckSigmas(const Config& c) {
  const double max = MaxFoldFreeSigmaPerMm2(c.ideal_image, c.distortion);
  for (size_t i = 0; i < c.distortion.sigmas_per_mm2.size(); ++i) {
    const double sigma = c.distortion.sigmas_per_mm2[i];
    if (!(std::abs(sigma) < max) && sigma != 0) {
      throw util::ConfigError(
          fmt::format("{}: distortion.sigmas_per_mm2[{}]: |{}| mm^-2 folds the image (must be below "
                      "{:.3g} for rhoN_mm and MT; docs/robustness.md)",
                      c.path, i, sigma, max));
    }
  }
}

void ParseReconstruction(Section s, ReconstructionSettings& p) {
  p.method = s.String("method", p.method);
  if (p.method != "iterative" && p.method != "paper") {
    s.Fail(s.Key("method"), fmt::format("must be \"iterative\" or \"paper\" (got \"{}\")", p.method));
  }
  p.taylor_degree = s.Integer("taylor_degree", p.taylor_degree);
  if (p.taylor_degree < 2 || p.taylor_degree > 14) {
    s.Fail(s.Key("taylor_degree"), fmt::format("must lie in [2, 14] (got {})", p.taylor_degree));
  }
  p.vertex_t_um = s.Number("vertex_t_um", p.vertex_t_um);
  p.vertex_search_halfwidth_um = s.Number("vertex_search_halfwidth_um", p.vertex_search_halfwidth_um);
  s.Positive("vertex_search_halfwidth_um", p.vertex_search_halfwidth_um);
  p.vertex_search_steps = s.Integer("vertex_search_steps", p.vertex_search_steps);
  s.AtLeast("vertex_search_steps", p.vertex_search_steps, 3);
  p.vertex_search_tol = s.Number("vertex_search_tol", p.vertex_search_tol);
  s.Positive("vertex_search_tol", p.vertex_search_tol);
  p.vertex_search_max_refinements = s.Integer("vertex_search_max_refinements", p.vertex_search_max_refinements);
  s.AtLeast("vertex_search_max_refinements", p.vertex_search_max_refinements, 1);
  p.max_iterations = s.Integer("max_iterations", p.max_iterations);
  s.AtLeast("max_iterations", p.max_iterations, 1);
  p.convergence_um = s.Number("convergence_um", p.convergence_um);
  s.Positive("convergence_um", p.convergence_um);
  p.power_map_radius_mm = s.Number("power_map_radius_mm", p.power_map_radius_mm);
  s.Positive("power_map_radius_mm", p.power_map_radius_mm);
  p.power_map_method = s.String("power_map_method", p.power_map_method);
  if (p.power_map_method != "exact" && p.power_map_method != "polynomial") {
    s.Fail(s.Key("power_map_method"), fmt::format("must be \"exact\" or \"polynomial\" (got \"{}\")", p.power_map_method));
  }
  p.power_map_meridians = s.Integer("power_map_meridians", p.power_map_meridians);
  s.AtLeast("power_map_meridians", p.power_map_meridians, 4);
  p.power_map_radial_samples = s.Integer("power_map_radial_samples", p.power_map_radial_samples);
  s.AtLeast("power_map_radial_samples", p.power_map_radial_samples, 10);
  p.spot_uncertainty_um = s.Number("spot_uncertainty_um", p.spot_uncertainty_um);
  s.Positive("spot_uncertainty_um", p.spot_uncertainty_um);
  p.surface_model_given = s.Has("surface_model");
  p.surface_model = s.String("surface_model", p.surface_model);
  if (p.surface_model != "polynomial" && p.surface_model != "spline" && p.surface_model != "auto") {
    s.Fail(s.Key("surface_model"),
           fmt::format("must be \"polynomial\", \"spline\" or \"auto\" (got \"{}\")", p.surface_model));
  }
  p.spline_spacing_mm = s.Number("spline_spacing_mm", p.spline_spacing_mm);
  if (!(p.spline_spacing_mm >= 0.1 && p.spline_spacing_mm <= 2.0)) {
    s.Fail(s.Key("spline_spacing_mm"), fmt::format("must lie in [0.1, 2] mm (got {})", p.spline_spacing_mm));
  }
  p.biconic_fit = s.String("biconic_fit", p.biconic_fit);
  if (p.biconic_fit != "free-apex" && p.biconic_fit != "paper" && p.biconic_fit != "sphere") {
    s.Fail(s.Key("biconic_fit"),
           fmt::format("must be \"free-apex\", \"paper\" or \"sphere\" (got \"{}\")", p.biconic_fit));
  }
  s.RejectUnknown();
}

// Physical consistency across sections: every designed ray must reach the cone, and the cornea must be defined
// wherever the rays land on it.
void CheckGeometry(const Config& c) {
  const auto design = DesignNullScreen(c.ideal_image, c.topographer);
  if (!design.failures.empty()) {
    const auto& f = design.failures.front();
    throw util::ConfigError(
        fmt::format("{}: topographer: {} of {} spots cannot be designed (first: ring {} index {}: {})", c.path,
                    design.failures.size(), c.ideal_image.SpotCount(), f.id.ring, f.id.index, f.reason));
  }
  double landing_mm = 0;
  for (const auto& t : design.targets) landing_mm = std::max(landing_mm, t.on_sphere_mm.head<2>().norm());
  // Rays on a cornea land near where they land on the reference sphere; 10 % margin covers the paper's range of
  // corneas (the spread of landing radii between r = 7.2 and 8.4 mm is ~6 %).
  const double needed_mm = 1.1 * landing_mm;
  const Biconic b{c.cornea};
  if (b.DefinedRadiusMm() < needed_mm) {
    const double qx = (1 + c.cornea.kx) / (c.cornea.rx_mm * c.cornea.rx_mm);
    const double qy = (1 + c.cornea.ky) / (c.cornea.ry_mm * c.cornea.ry_mm);
    throw util::ConfigError(
        fmt::format("{}: cornea.{}: the biconic is undefined beyond rho = {:.3f} mm but rays land out "
                    "to {:.3f} mm (conic constant too large for its radius)",
                    c.path, qx >= qy ? "kx" : "ky", b.DefinedRadiusMm(), needed_mm));
  }
}

}  // namespace

double MaxFoldFreeSigmaPerMm2(const IdealImageParams& image, const DistortionSweep& distortion) {
  constexpr double kCorneaMargin = 1.1;
  const double r_max_mm = kCorneaMargin * (std::abs(image.rhoN_mm) + std::hypot(distortion.centre_x_mm, distortion.centre_y_mm));
  return SeidelRadial::MaxFoldFreeSigmaPerMm2(distortion.magnification, r_max_mm);
}

Config ParseConfig(const std::string& json_text, const std::string& origin) {
  const json j = util::ParseJsonStrict(json_text, origin);
  Config c;
  c.path = origin;
  Section top(j, origin, "");
  ParseIdealImage(top.Child("ideal_image"), c.ideal_image);
  ParseTopographer(top.Child("topographer"), c.topographer);
  ParseCornea(top.Child("cornea"), c.cornea);
  ParseDistortion(top.Child("distortion"), c.distortion);
  if (top.Has("reconstruction")) ParseReconstruction(top.Child("reconstruction"), c.reconstruction);
  if (top.Has("eye")) {
    c.eye = top.String("eye");
    if (c.eye != "OD" && c.eye != "OS") {
      top.Fail(top.Key("eye"), fmt::format("must be \"OD\" (right) or \"OS\" (left) (got \"{}\")", c.eye));
    }
  }
  top.RejectUnknown();
  CheckSigmas(c);
  CheckGeometry(c);
  return c;
}

Config LoadConfig(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw util::ConfigError(fmt::format("{}: (file): cannot be opened for reading", path));
  util::NoteInput(path);
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw util::ConfigError(fmt::format("{}: (file): read error", path));
  return ParseConfig(ss.str(), path);
}

std::string ConfigToJson(const Config& c) {
  json j;
  j["ideal_image"] = {{"rho0_mm", c.ideal_image.rho0_mm}, {"rhoN_mm", c.ideal_image.rhoN_mm},
                      {"rings_N", c.ideal_image.rings_N}, {"eta0", c.ideal_image.eta0},
                      {"eta", c.ideal_image.eta}, {"spot_radius_um", c.ideal_image.spot_radius_um}};
  if (c.ideal_image.orientation_key) j["ideal_image"]["orientation_key"] = true;  // absent: the paper's design
  j["topographer"] = {{"a_mm", c.topographer.a_mm}, {"b_mm", c.topographer.b_mm}, {"re_mm", c.topographer.re_mm},
                      {"cone_semi_angle_deg", c.topographer.cone_semi_angle_deg},
                      {"cone_vertex_z_mm", c.topographer.cone_vertex_z_mm}};
  j["cornea"] = {{"rx_mm", c.cornea.rx_mm}, {"ry_mm", c.cornea.ry_mm}, {"kx", c.cornea.kx}, {"ky", c.cornea.ky},
                 {"alpha_deg", c.cornea.alpha_deg}, {"x0_mm", c.cornea.x0_mm}, {"y0_mm", c.cornea.y0_mm},
                 {"z0_mm", c.cornea.z0_mm}, {"tilt_x_deg", c.cornea.tilt_x_deg},
                 {"tilt_y_deg", c.cornea.tilt_y_deg}};
  j["distortion"] = {{"model", c.distortion.model}, {"MT", c.distortion.magnification},
                     {"centre_x_mm", c.distortion.centre_x_mm}, {"centre_y_mm", c.distortion.centre_y_mm},
                     {"sigmas_per_mm2", c.distortion.sigmas_per_mm2}};
  const auto& r = c.reconstruction;
  j["reconstruction"] = {{"method", r.method}, {"taylor_degree", r.taylor_degree},
                         {"vertex_t_um", r.vertex_t_um},
                         {"vertex_search_halfwidth_um", r.vertex_search_halfwidth_um},
                         {"vertex_search_steps", r.vertex_search_steps}, {"vertex_search_tol", r.vertex_search_tol},
                         {"vertex_search_max_refinements", r.vertex_search_max_refinements},
                         {"max_iterations", r.max_iterations}, {"convergence_um", r.convergence_um},
                         {"power_map_radius_mm", r.power_map_radius_mm},
                         {"power_map_method", r.power_map_method},
                         {"power_map_meridians", r.power_map_meridians},
                         {"power_map_radial_samples", r.power_map_radial_samples},
                         {"spot_uncertainty_um", r.spot_uncertainty_um}, {"surface_model", r.surface_model},
                         {"spline_spacing_mm", r.spline_spacing_mm}, {"biconic_fit", r.biconic_fit}};
  if (!c.eye.empty()) j["eye"] = c.eye;  // absent: not stated
  return j.dump(2);
}

}  // namespace topocal::model

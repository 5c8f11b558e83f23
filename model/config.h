#pragma once
// The topographer configuration (JSON), paper Tables I-IV. Schema, units and validation rules are documented in
// README.md ("Configuration"). Loading is strict: an unknown key, a missing key, a value of the wrong type or a
// non-physical value throws ConfigError whose message is one line "FILE: KEY: problem".
//
// Frame: cornea vertex at the origin, sag towards +z, pinhole at z = -b, detection plane at z = -a-b, cone vertex
// at z = cone_vertex_z_mm (negative: behind the pinhole), the cornea rotated by +alpha about z
// (x_r = x cos a + y sin a, y_r = -x sin a + y cos a; see docs/paper-decisions.md, item 5).
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "model/distortion.h"
#include "util/io.h"
#include "model/paper_topographer.h"

namespace topocal::model {

struct IdealImageParams {
  double rho0_mm = 0.031;  // radius of the first ring (Table I)
  double rhoN_mm = 0.35;   // radius of the last ring
  int rings_N = 11;        // N: there are N + 1 rings
  int eta0 = 8;            // spots on the first ring
  int eta = 8;             // extra spots per ring
  double spot_radius_um = 8.0;  // radius of each ideal-image circle (only for drawing the null screen)
  // Optional (false): leave three spots out of the printed screen so that the pattern's orientation is observable
  // (model::OrientationKeySpots, docs/image-orientation.md). False keeps the paper's design.
  bool orientation_key = false;
  int SpotCount() const { return (rings_N + 1) * eta0 + eta * rings_N * (rings_N + 1) / 2; }
};

struct TopographerParams {
  double a_mm = kPaperAMm;             // pinhole to detection plane
  double b_mm = 70.0;                  // pinhole to corneal vertex
  double re_mm = 7.8;                  // radius of the reference sphere the null screen is designed for
  double cone_semi_angle_deg = 10.79;  // phi_c
  double cone_vertex_z_mm = -85.5;     // z_c (see docs/paper-decisions.md: the paper prints +85.5)
};

struct BiconicParams {
  double rx_mm = 8.35;
  double ry_mm = 7.63;
  double kx = -0.43;
  double ky = -0.25;
  double alpha_deg = 17.0;
  double x0_mm = 0.0;  // decentration of the biconic in its own (rotated) frame, Eq. 12
  double y0_mm = 0.0;
  double z0_mm = 0.0;  // axial offset of the vertex (the paper's cornea sits at z = 0)
  // Tilt of the eye about its apex (model/surface.h): the surface of Eq. 12 is rotated by R = Ry(tilt_y) Rx(tilt_x)
  // about its vertex, angles in the instrument frame. 0 = the paper's eye, looking along the axis.
  double tilt_x_deg = 0.0;
  double tilt_y_deg = 0.0;
};

struct DistortionSweep {
  std::string model = "seidel";
  double magnification = kPaperMagnification;  // M_T
  double centre_x_mm = 0.0;
  double centre_y_mm = 0.0;
  std::vector<double> sigmas_per_mm2;
  // The sweep's Seidel distortion (paper Eq. 18) at one sigma: its magnification and centre, the sigma given. The one
  // place a sweep turns into a distortion (the sweep, the harness, the closed loop and render-spots use it).
  SeidelParams SeidelAt(double sigma_per_mm2) const noexcept {
    SeidelParams s;
    s.sigma_per_mm2 = sigma_per_mm2;
    s.magnification = magnification;
    s.centre_x_mm = centre_x_mm;
    s.centre_y_mm = centre_y_mm;
    return s;
  }
};

// Settings of the null-screen reconstruction (optional section "reconstruction"; see README.md).
struct ReconstructionSettings {
  std::string method = "iterative";  // "iterative" (normal refinement, default) or "paper" (vertex search of Fig. 8)
  int taylor_degree = 10;            // Taylor polynomial degree: 10 (66 terms); 9 is the paper's 55 terms
                                     // (docs/reconstruction.md: degree 9 cannot hold other corneas to 0.05 um)
  double vertex_t_um = 0.0;                  // axial position of G's vertex / Psi(0,0): the nominal working distance
  double vertex_search_halfwidth_um = 20.0;  // half-width of the first t_k interval around vertex_t_um (paper method)
  int vertex_search_steps = 11;              // K, points per t_k interval (paper method)
  double vertex_search_tol = 2e-7;           // TOL of Fig. 8
  int vertex_search_max_refinements = 30;
  int max_iterations = 50;                   // iterative method: outer iterations
  double convergence_um = 1e-4;              // iterative method: stop when no point moves more than this (0.1 nm)
  double power_map_radius_mm = 5.3;          // radius of the power maps (paper's pv values: ~5.3 mm), the same
                                             // for every input so that maps compare; coverage is reported
  std::string power_map_method = "exact";    // "exact" derivatives of Psi or "polynomial" (Eq. 23 meridian fit)
  int power_map_meridians = 360;
  int power_map_radial_samples = 100;
  double spot_uncertainty_um = 0.045;        // spot-centre uncertainty on the detection plane (0.04 px of the
                                             // 1.12 um pixel of data/device.json): the noise the model-adequacy
                                             // figure compares the slope residual with
  std::string surface_model = "polynomial";  // "polynomial" (Psi alone, the paper's Eq. 21), "spline" (Psi plus
                                             // a bicubic P-spline residual, REML-smoothed: freeform corneas;
                                             // docs/reconstruction.md) or "auto" (the spline only when the
                                             // polynomial does not fit the data: topo::ModelFitsData)
  bool surface_model_given = false;          // the configuration (or --surface-model) named surface_model; when
                                             // it did not, `reconstruct` (the verb that measures eyes) takes
                                             // "auto" and everything that reproduces or sweeps the paper keeps
                                             // the polynomial (docs/reconstruction.md, "The default surface model")
  double spline_spacing_mm = 0.33;           // knot spacing of the spline residual (spots lie ~0.35 mm apart)
  std::string biconic_fit = "free-apex";     // "free-apex" (apex position and tilt free, default), "paper" or "sphere" (topo/sphere_fit.h)
                                             // (Eq. 12 with x0 = y0 = 0 and no tilt: the paper's 6 parameters)
};

struct Config {
  std::string path;  // where it was loaded from, for messages
  IdealImageParams ideal_image;
  TopographerParams topographer;
  BiconicParams cornea;
  DistortionSweep distortion;
  ReconstructionSettings reconstruction;
  std::string eye;  // the eye measured, "OD" (right) or "OS" (left); empty when not stated (`--eye` overrides it)
};

// The largest |sigma| (mm^-2) of Seidel distortion (paper Eq. 18) the configured image can take without folding:
// the radial map r -> r (1 + c r^2), c = sigma / M_T^3, is monotonic while 1 + 3 c r^2 > 0, so for every r up to
// r_max = 1.1 (rhoN_mm + |centre|) (10 % for corneas other than the design's) |sigma| < |M_T|^3 / (3 r_max^2).
// Beyond it barrel distortion folds the image onto itself and sigma ~ 1e308 computes Inf positions.
// The paper's largest sigma, 2e-4, is 30 % of it.
double MaxFoldFreeSigmaPerMm2(const IdealImageParams& image, const DistortionSweep& distortion);

// Loads and validates a configuration file. Throws ConfigError ("FILE: KEY: problem").
Config LoadConfig(const std::string& path);
// Parses and validates JSON text; `origin` names the source in messages.
Config ParseConfig(const std::string& json_text, const std::string& origin);
// The configuration as JSON text (the same schema LoadConfig reads).
std::string ConfigToJson(const Config& config);

}  // namespace topocal::model

#pragma once
// Axial (sagittal) and tangential (meridional) curvature and power maps (paper Sec. 4.2, Eq. 23-25, 28).
//
// Along each meridian theta the sag is F(rho) = surface(rho cos theta, rho sin theta). Its derivatives come either
//  * kPolynomialFit: from the least-squares polynomial F(rho) = sum_{i=1..8} c_i rho^i (Eq. 23 as printed; no
//    constant term: the piston and tilts of Psi are zeroed first, so F(0) = 0), or
//  * kExact (default): from the surface's own gradient and Hessian, F' = grad S . e, F'' = e^T H e with
//    e = (cos theta, sin theta). For Psi (degree 9) the two agree to ~1e-3 D, since Psi along a meridian is itself a
//    polynomial of degree 9; for a sphere or biconic the order-8 fit leaves +-0.1 D of model error over 5.3 mm
//    (docs/equations.md, Eq. 23; tests/topo/power_map_test.cc), which is why exact derivatives are the default;
//
//   K_a = F' / (rho (1 + F'^2)^(1/2)),   K_m = F'' / (1 + F'^2)^(3/2)          (Eq. 24, 1/mm)
//   P = (n_c - n') K * 1000                                                     (Eq. 25, diopters)
// with the keratometric index n_c = 1.3375 and n' = 1. Samples: rho_k = R k / K, k = 1..K (rho = 0 is excluded:
// K_a is a limit there), theta_j = 360 j / M deg, j = 0..M-1.
#include <functional>
#include <string>
#include <vector>

#include "model/keratometry.h"
#include "model/surface.h"
#include "topo/taylor_polynomial.h"

namespace topocal::topo {

inline constexpr double kKeratometricIndex = model::kKeratometricIndex;  // paper Sec. 4.2 (model/keratometry.h)

enum class MeridianMethod { kExact, kPolynomialFit };

// Evaluates the surface and its derivatives at (x, y) mm; false where it is undefined.
using SurfaceEvaluator = std::function<bool(double x_mm, double y_mm, model::SurfaceDerivatives*)>;

struct PowerMapOptions {
  MeridianMethod method = MeridianMethod::kExact;
  double radius_mm = 5.3;
  int meridians = 360;
  int radial_samples = 100;
  int meridian_polynomial_order = 8;  // Eq. 23
  double corneal_index = kKeratometricIndex;
  double surrounding_index = 1.0;
  // The surface is point-symmetric about the axis (S(-x, -y) = S(x, y): a centred, untilted biconic), so meridian
  // theta + 180 deg has meridian theta's profile F, F', F''. With an even number of meridians the second half of
  // the maps is then a copy of the first (half the surface evaluations); ignored for an odd number.
  bool point_symmetric = false;
};

struct PowerMaps {
  int meridians = 0;
  int radial_samples = 0;
  double radius_mm = 0;
  std::vector<double> axial_D;       // [meridian * radial_samples + k]
  std::vector<double> tangential_D;
  double pv_axial_D = 0;      // Eq. 28b (the paper's pv_a, Table VII column "pv_s")
  double pv_tangential_D = 0; // Eq. 28a (pv_m)
  double RhoMm(int k) const { return radius_mm * (k + 1) / radial_samples; }
  double ThetaDeg(int j) const { return 360.0 * j / meridians; }
};

// The sag F and its radial derivatives F', F'' along the meridian at angle theta, at n radii; false where the
// surface is undefined.
using MeridianSampler =
    std::function<bool(double theta_rad, int n, const double* rho_mm, double* f, double* df, double* d2f)>;

// The surface must be defined on the whole disc of radius options.radius_mm. Returns false with a reason if it
// is not, if the meridian fits are singular, or if a curvature is not finite.
bool ComputePowerMaps(const MeridianSampler& meridians, const PowerMapOptions& options, PowerMaps* maps,
                      std::string* why = nullptr);
// Any surface through its gradient and Hessian.
bool ComputePowerMaps(const SurfaceEvaluator& surface, const PowerMapOptions& options, PowerMaps* maps,
                      std::string* why = nullptr);
// The Taylor polynomial Psi: along a meridian it is a polynomial in rho, evaluated by Horner's rule (~10x faster
// than the 2-D derivatives at every sample; the sweep's hot path).
bool ComputePowerMaps(const TaylorPolynomial& psi, const PowerMapOptions& options, PowerMaps* maps,
                      std::string* why = nullptr);

// Area-weighted mean of the axial power over the disc of this radius (samples weighted by rho, the polar area
// element): the "central power" a keratometer-like reading gives, e.g. over 3 mm diameter. NaN if no sample lies
// in the disc.
double MeanAxialPowerD(const PowerMaps& maps, double radius_mm);

}  // namespace topocal::topo

#pragma once
// The solver settings the surface fits share (topo/biconic_fit.cc, topo/sphere_fit.cc): dense QR, one thread, and
// tolerances tight enough that an exact point cloud comes back at the least-squares optimum to ~1e-12 mm (the
// conic constants are weakly determined, and in free-apex mode tilt and decentration nearly trade against each
// other, so Ceres' default 1e-6 relative cost change would stop far short).
#include <ceres/solver.h>

namespace topocal::topo {

inline ceres::Solver::Options SurfaceFitSolverOptions(int max_iterations) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = max_iterations;
  so.function_tolerance = 1e-16;
  so.gradient_tolerance = 1e-16;
  so.parameter_tolerance = 1e-14;
  so.num_threads = 1;
  return so;
}

// A fit started at the optimum of a cloud that differs by micrometres or less (a Monte Carlo draw started from its
// nominal fit): that start is inside the quadratic region, so the trust region opens at Ceres' largest radius
// (Gauss-Newton steps: Levenberg-Marquardt's damping would only slow the weakly determined directions, the conic
// constants and tilt against decentration), and two steps reach the optimum. The fit then stops at the first step
// that changes the cost by less than 1e-11 of itself, taken or not: near the optimum the next Gauss-Newton step is
// rounding (its cost change ~1e-18 against a cost of ~5e-6 mm^2 for the paper cornea, a relative 5e-13, of either
// sign) but in the weakly determined directions it is ~1e-10 of the parameters, above the 1e-12 step tolerance, and
// the solver rejected it again and again while the trust region shrank from 1e16 to the step's size: 20 iterations
// instead of 3 (issue 15). A cost change of 1e-11 relative is a step of sqrt(1e-11 n) ~ 1e-4 of the fit's own
// standard deviations (n = 624 points), and Gauss-Newton's last real step is far below that.
// Measured on the demo unit's draws (2026-12-02): 3 iterations for the paper cornea and 2-3 for the sphere; the
// fits agree with a cold fit to 1e-10 mm (tests/topo/sphere_fit_test.cc, tests/topo/reconstruction_test.cc).
inline ceres::Solver::Options WarmStartSolverOptions(int max_iterations) {
  ceres::Solver::Options so = SurfaceFitSolverOptions(max_iterations);
  so.initial_trust_region_radius = so.max_trust_region_radius;
  so.parameter_tolerance = 1e-12;
  so.function_tolerance = 1e-11;
  return so;
}

}  // namespace topocal::topo

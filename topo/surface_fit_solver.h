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
// constants and tilt against decentration), and the fit stops at a step of 1e-12 of the parameters. Two steps reach
// the optimum; with the cold fit's 1e-14 the solver went on with 3-9 rounding-level steps, most of them rejected.
// Measured on the demo unit's paper-cornea draws (2026-12-02): 7-12 -> 3 iterations, k and r within 6e-14 of the
// cold tolerances' optimum.
inline ceres::Solver::Options WarmStartSolverOptions(int max_iterations) {
  ceres::Solver::Options so = SurfaceFitSolverOptions(max_iterations);
  so.initial_trust_region_radius = so.max_trust_region_radius;
  so.parameter_tolerance = 1e-12;
  return so;
}

}  // namespace topocal::topo

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

}  // namespace topocal::topo

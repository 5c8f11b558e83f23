#pragma once
// The solver settings the surface fits share (topo/biconic_fit.cc, topo/sphere_fit.cc): one thread, the normal
// equations by dense Cholesky, and tolerances that stop at the first step the cost can no longer resolve.
//
// Why Cholesky: the problems are a few hundred to a few thousand residuals in 4-10 parameters; forming J^T J
// (Ceres scales the columns first) and factoring 10 x 10 costs a fraction of the Householder QR of the whole
// Jacobian at every step (free-apex fit of the paper cornea 0.80 -> 0.70 ms). Squaring the condition number only
// perturbs the steps; the fit converges to the same optimum (exact clouds within 1.1e-13 instead of 6e-14,
// the paper sweep's fits within the changes the tolerances below make).
//
// Why these tolerances: the conic constants are weakly determined, and in free-apex mode tilt and decentration
// nearly trade against each other, so Ceres' default 1e-6 relative cost change stops far short of the optimum.
// At the other end, the cost itself is only known to rounding: the residuals are differences of sags ~1 mm
// computed to ~1e-16 mm, so the cost of the paper cornea's free-apex fit varies by ~1e-12 of itself between
// parameter vectors closer than the optimum is determined. With 1e-16 the solver went on after convergence with
// 3-9 such rounding-level steps, most of them rejected (each a cost evaluation and a factorisation: half of
// every fit's time; docs/performance.md). Now a fit stops when
//  - the cost changes by <= 1e-12 of itself: a Gauss-Newton step that lowers the cost by that little moves the
//    parameters by <= sqrt(1e-12 n) of their own standard deviations (n points; 2.5e-5 sigma for 624), or
//  - the step is <= 1e-13 of the parameter vector's norm (was 1e-14): this ends the fits whose cost is too small
//    to show any change (exact clouds, which come back to ~6e-14 as before).
// Measured over the paper sweep: the free-apex fits 7-14 -> 5-6 iterations and the clinical best-fit spheres 5-14
// -> 5, every fitted number within 8e-11 (k, r in mm) and the best-fit sphere within 2e-8 mm of the 1e-16 fits.
#include <ceres/solver.h>

namespace topocal::topo {

inline ceres::Solver::Options SurfaceFitSolverOptions(int max_iterations) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  so.max_num_iterations = max_iterations;
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-16;
  so.parameter_tolerance = 1e-13;
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
// instead of 3. A cost change of 1e-11 relative is a step of sqrt(1e-11 n) ~ 1e-4 of the fit's own
// standard deviations (n = 624 points), and Gauss-Newton's last real step is far below that.
// Measured on the demo unit's draws (2026-12-02): 3 iterations for the paper cornea and 2-3 for the sphere; the
// fits agree with a cold fit to ~1e-9 mm (tests/topo/sphere_fit_test.cc, tests/topo/reconstruction_test.cc).
inline ceres::Solver::Options WarmStartSolverOptions(int max_iterations) {
  ceres::Solver::Options so = SurfaceFitSolverOptions(max_iterations);
  so.initial_trust_region_radius = so.max_trust_region_radius;
  so.parameter_tolerance = 1e-12;
  so.function_tolerance = 1e-11;
  return so;
}

}  // namespace topocal::topo

#pragma once
// Paper Eq. 25: the refractive power of a corneal curvature, P = (n_c - n') K, K in 1/m, P in diopters, with the
// keratometric index n_c = 1.3375 and air n' = 1 (paper Sec. 4.2). The one owner of the formula and the index: the
// power maps (topo/power_map.h), the reference spheres' true powers (pipeline/) and the refractive ablation of the
// freeform test set (model/freeform_terms.h) all go through here.
namespace topocal::model {

inline constexpr double kKeratometricIndex = 1.3375;

// Eq. 25 with K in 1/mm (hence the factor 1000): e.g. 1 / 7.8 mm -> 43.27 D.
constexpr double PowerFromCurvatureD(double curvature_per_mm, double corneal_index = kKeratometricIndex,
                                     double surrounding_index = 1.0) noexcept {
  return (corneal_index - surrounding_index) * 1000.0 * curvature_per_mm;
}
// Its inverse: the curvature change (1/mm) of a power change (D).
constexpr double CurvatureFromPowerPerMm(double power_D, double corneal_index = kKeratometricIndex,
                                         double surrounding_index = 1.0) noexcept {
  return power_D / ((corneal_index - surrounding_index) * 1000.0);
}

}  // namespace topocal::model

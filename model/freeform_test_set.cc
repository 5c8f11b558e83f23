#include "model/freeform_test_set.h"

#include <stdexcept>
#include "util/io.h"

namespace topocal::model {
namespace {

// Normal eyes are never centred: every entry sits off the axis (0.2-0.45 mm) and tilted (1.5-3 deg), a different
// direction each time.
BiconicParams Eye(double rx, double ry, double kx, double ky, double alpha_deg, int variant) {
  static constexpr double kOffsets[][4] = {{0.30, -0.20, 2.0, -1.0}, {-0.25, 0.35, -1.5, 2.0},
                                           {0.10, 0.40, 1.0, 2.5},   {-0.40, -0.15, -2.5, -1.5},
                                           {0.20, 0.20, 0.5, -3.0},  {-0.10, -0.30, 3.0, 0.5}};
  const auto& o = kOffsets[variant % 6];
  return BiconicParams{rx, ry, kx, ky, alpha_deg, o[0], o[1], 0.0, o[2], o[3]};
}

TestCornea Make(std::string name, std::string kind, const BiconicParams& base) {
  TestCornea c{std::move(name), std::move(kind), {}};
  c.surface.base = Biconic{base};
  return c;
}

}  // namespace

std::vector<TestCornea> FreeformTestSet() {
  std::vector<TestCornea> set;
  // Keratoconus: Gaussian cones 5-40 um, widths 0.8-1.5 mm, 0.5-1.5 mm off the centre, mostly inferior (-y).
  const struct { const char* name; double h_um, sigma_mm, x_mm, y_mm; } cones[] = {
      {"kc-5um-0.8mm", 5.0, 0.8, -0.4, -0.5},     {"kc-12um-1.3mm", 11.6, 1.3, 0.3, -0.9},
      {"kc-14um-0.87mm-nipple", 13.9, 0.87, 0.2, -0.5}, {"kc-20um-1.0mm", 20.0, 1.0, 1.0, -0.8},
      {"kc-33um-0.85mm", 33.0, 0.85, -0.5, -1.0}, {"kc-40um-1.5mm", 40.0, 1.5, 0.6, -1.35}};
  int v = 0;
  for (const auto& c : cones) {
    auto t = Make(c.name, "keratoconus", Eye(7.5, 7.3, -0.3, -0.2, 20.0 + 30.0 * v, v));
    t.surface.cones.push_back({c.h_um, c.sigma_mm, c.x_mm, c.y_mm});
    set.push_back(std::move(t));
    ++v;
  }
  // Ablations: myopic and hyperopic, +-2 to +-6 D over a 6 mm zone with a 1 mm blend; the -5 D one decentred.
  const struct { const char* name; double power_D, x_mm, y_mm; } ablations[] = {
      {"lasik-myopic-2D", -2.0, 0.0, 0.0}, {"lasik-myopic-4D", -4.0, 0.0, 0.0},
      {"lasik-myopic-5D-decentred", -5.0, 0.4, -0.3}, {"lasik-myopic-6D", -6.0, 0.0, 0.0},
      {"lasik-hyperopic-2D", 2.0, 0.0, 0.0}, {"lasik-hyperopic-4D", 4.0, 0.0, 0.0},
      {"lasik-hyperopic-6D", 6.0, 0.0, 0.0}};
  for (const auto& a : ablations) {
    auto t = Make(a.name, "ablation", Eye(7.8, 7.7, -0.25, -0.2, 80.0, v));
    t.surface.ablations.push_back({a.power_D, 6.0, 1.0, a.x_mm, a.y_mm});
    set.push_back(std::move(t));
    ++v;
  }
  // Irregular astigmatism: Zernike terms up to 6th order, 1-3 um over a 4 mm radius.
  {
    auto t = Make("irregular-coma-trefoil", "irregular", Eye(7.8, 7.6, -0.2, -0.3, 10.0, v++));
    t.surface.zernike = {{3, -1, 3.0, 4.0, 0, 0}, {3, 3, 1.5, 4.0, 0, 0}};
    set.push_back(std::move(t));
  }
  {
    auto t = Make("irregular-4th-6th", "irregular", Eye(7.7, 7.5, -0.3, -0.1, 135.0, v++));
    t.surface.zernike = {{4, 2, 2.0, 4.0, 0, 0}, {4, -4, 1.0, 4.0, 0, 0}, {5, 1, 1.5, 4.0, 0, 0}, {6, 0, 1.0, 4.0, 0, 0},
                         {6, -2, 1.0, 4.0, 0, 0}};
    set.push_back(std::move(t));
  }
  // Biconics over r 7.0-9.0 mm, k -1.0..+0.5, toric differences to 1.5 mm at any axis.
  const struct { const char* name; double rx, ry, kx, ky, alpha; } biconics[] = {
      {"biconic-flat-prolate", 9.0, 8.8, -1.0, -0.8, 30.0},
      {"biconic-steep-oblate", 7.0, 7.1, 0.5, 0.3, 100.0},
      {"biconic-toric-1.4mm", 8.7, 7.3, -0.3, 0.1, 95.0},
      {"biconic-toric-1.5mm-oblique", 8.5, 7.0, -0.6, 0.4, 140.0}};
  for (const auto& b : biconics) set.push_back(Make(b.name, "biconic", Eye(b.rx, b.ry, b.kx, b.ky, b.alpha, v++)));
  // Positioned as the instrument positions an eye: the point on its axis at the working distance.
  for (auto& c : set) FocusOnAxis(&c.surface);
  return set;
}

std::vector<TestCornea> FreeformTestSubset(const std::vector<std::string>& names) {
  const auto all = FreeformTestSet();
  std::vector<TestCornea> out;
  for (const auto& n : names) {
    bool found = false;
    for (const auto& c : all) {
      if (c.name == n) {
        out.push_back(c);
        found = true;
      }
    }
    if (!found) throw util::InputError("freeform test set: no cornea named \"" + n + "\"");
  }
  return out;
}

}  // namespace topocal::model

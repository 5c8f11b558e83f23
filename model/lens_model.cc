#include "model/lens_model.h"

#include <cmath>
#include <limits>

#include "model/invert_by_newton.h"

namespace topocal::model {
namespace {

template <LensModel M>
std::string_view NameOf(LensNaming naming) noexcept {
  switch (naming) {
    case LensNaming::kDevice: return M::kDeviceName;
    case LensNaming::kRos: return M::kRosName;
    case LensNaming::kMrcal: return M::kMrcalName;
    case LensNaming::kTopocal: break;
  }
  return M::kName;
}

}  // namespace

std::string_view LensModelName(const LensModelId& lens, LensNaming naming) noexcept {
  return std::visit([naming](auto m) { return NameOf<decltype(m)>(naming); }, lens);
}

std::optional<LensModelId> LensModelFromName(std::string_view name, LensNaming naming) noexcept {
  std::optional<LensModelId> out;
  ForEachLensModel([&](auto m) {
    if (!out && NameOf<decltype(m)>(naming) == name) out = m;
  });
  return out;
}

std::string LensModelNames(std::string_view separator, LensNaming naming) {
  std::string out;
  ForEachLensModel([&](auto m) {
    if (!out.empty()) out += separator;
    out += NameOf<decltype(m)>(naming);
  });
  return out;
}

int LensParameterCount(const LensModelId& lens) noexcept {
  return std::visit([](auto m) { return static_cast<int>(decltype(m)::kNumParams); }, lens);
}

std::span<const std::string_view> LensParameterNames(const LensModelId& lens) noexcept {
  return std::visit([](auto m) { return std::span<const std::string_view>(decltype(m)::kParameterNames); }, lens);
}

LensModelId SmallestLensModelFor(const LensCoefficients& k) noexcept {
  int used = 0;
  for (int i = 0; i < kMaxLensParams; ++i) {
    if (k[static_cast<size_t>(i)] != 0.0) used = i + 1;
  }
  std::optional<LensModelId> best;
  ForEachLensModel([&](auto m) {
    if (!best && decltype(m)::kNumParams >= used) best = m;
  });
  return best.value_or(LensModelId{});
}

bool UndistortNormalized(const LensModelId& lens, const double* k, const double* xd, double* xn,
                         double tolerance) noexcept {
  return std::visit(
      [&](auto m) {
        using M = decltype(m);
        const auto forward = [k](const auto* in, auto* out) {
          using T = std::remove_cv_t<std::remove_reference_t<decltype(in[0])>>;
          T kk[M::kNumParams];
          for (int i = 0; i < M::kNumParams; ++i) kk[i] = T(k[i]);
          M::DistortNormalized(kk, in, out);
        };
        return InvertByNewton(forward, xd, xn, tolerance);
      },
      lens);
}

double RadialSlope(const LensModelId& lens, const double* k, double s) noexcept {
  using Jet = ceres::Jet<double, 1>;
  return std::visit(
      [&](auto m) {
        using M = decltype(m);
        Jet kk[M::kNumParams];
        for (int i = 0; i < M::kNumParams; ++i) kk[i] = Jet(k[i]);
        const Jet g = M::RadialFactor(kk, Jet(s, 0));
        if (!(g.a > 0)) return -std::numeric_limits<double>::infinity();
        return g.a + 2.0 * s * g.v[0];
      },
      lens);
}

}  // namespace topocal::model

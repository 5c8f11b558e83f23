#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "plot/map_image.h"
#include "plot/map_ticks.h"
#include "util/io.h"

namespace topocal::plot {
namespace {

// At most this many ticks or band boundaries on a colour bar: the loops below are counted, not stepped, so that a
// step below the values' rounding (1e16 + 1 over a step of 0.2) or a huge range cannot make them run or allocate
// without bound; the two ends stand in where no such scale exists.
constexpr double kMaxTicks = 1000;

}  // namespace

// A round step (1, 2 or 5 times a power of ten) of at least range / target_count.
double NiceStep(double range, double target_count) {
  const double raw = range / target_count;
  if (!(raw > 0) || !std::isfinite(raw)) return 1.0;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double f : {1.0, 2.0, 5.0, 10.0}) {
    if (f * mag >= raw * (1 - 1e-9)) return f * mag;
  }
  return 10.0 * mag;
}



std::vector<double> Ticks(double lo, double hi, double step) {
  const double eps = 1e-9 * step;
  const double first = std::ceil((lo - eps) / step);
  const double count = std::floor((hi + eps) / step) - first + 1;
  if (!std::isfinite(first) || !std::isfinite(count) || count > kMaxTicks || std::abs(first) > 1e15) {
    return {lo, hi};
  }
  std::vector<double> t;
  for (int i = 0; i < static_cast<int>(count); ++i) {
    const double v = (first + i) * step;
    t.push_back(std::abs(v) < eps ? 0.0 : v);
  }
  return t;
}

// value_min + k step up to value_max: the band boundaries of a stepped scale.
std::vector<double> StepTicks(double lo, double hi, double step) {
  const double count = std::floor((hi - lo) / step + 1e-9) + 1;
  if (!std::isfinite(count) || count > kMaxTicks || !(count >= 1)) return {lo, hi};
  std::vector<double> t;
  for (int k = 0; k < static_cast<int>(count); ++k) t.push_back(lo + k * step);
  return t;
}

// Decimals that print every multiple of `step` exactly (1.5 -> 1, 0.25 -> 2, 5 -> 0).
int Decimals(double step) {
  for (int k = 0; k < 9; ++k) {
    const double scaled = step * std::pow(10.0, k);
    if (std::abs(scaled - std::round(scaled)) < 1e-6 * std::max(1.0, scaled)) return k;
  }
  return 9;
}

bool MapScaleRequest::IsValid(std::string* why) const {
  const auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (kind == MapScaleKind::kAbsolute) {
    if (!(step > 0) || !std::isfinite(step)) return fail("an absolute scale needs a finite step > 0");
    if (low.has_value() != high.has_value()) return fail("an absolute scale's low and high go together");
    if (low && !(std::isfinite(*low) && std::isfinite(*high) && *high > *low)) {
      return fail("an absolute scale needs finite low < high");
    }
    if (low) {
      const double steps = (*high - *low) / step;
      if (std::abs(steps - std::round(steps)) > 1e-9 * std::max(1.0, steps)) {
        return fail("an absolute scale's high - low must be a whole number of steps");
      }
    }
  }
  if (!(min_span >= 0) || !std::isfinite(min_span)) return fail("min_span must be finite and >= 0");
  return true;
}

MapScaleRequest FittedStepScale(double step) {
  MapScaleRequest r;
  r.kind = MapScaleKind::kAbsolute;
  r.step = step;
  return r;
}

MapScaleRequest StandardPowerScale() {
  MapScaleRequest r = FittedStepScale(kStandardPowerStepD);
  r.low = kStandardPowerLowD;
  r.high = kStandardPowerHighD;
  return r;
}

MapScaleRequest ExtendedPowerScale() {
  MapScaleRequest r = FittedStepScale(kExtendedPowerStepD);
  r.low = kExtendedPowerLowD;
  r.high = kExtendedPowerHighD;
  return r;
}

MapScaleRequest NormalisedScale(double min_span) {
  MapScaleRequest r;
  r.kind = MapScaleKind::kNormalised;
  r.min_span = min_span;
  return r;
}

MapScaleRequest SymmetricScale(double min_span) {
  MapScaleRequest r = NormalisedScale(min_span);
  r.symmetric_about_zero = true;
  return r;
}

MapScale SelectMapScale(const std::vector<const GridMap*>& maps, const MapScaleRequest& request) {
  std::string why;
  if (!request.IsValid(&why)) throw util::InputError("MapScaleRequest: " + why);
  if (maps.empty()) throw util::InputError("SelectMapScale: no map");
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  std::string unit;
  for (const GridMap* m : maps) {
    if (!m) throw util::InputError("SelectMapScale: null map");
    unit = m->unit;
    for (double v : m->values) {
      if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    }
  }
  const bool has_data = std::isfinite(lo);
  const std::string set_word = maps.size() > 1 ? fmt::format("these {} maps'", maps.size()) : std::string("this map's");
  MapScale out;
  if (request.kind == MapScaleKind::kAbsolute) {
    const double step = request.step;
    double a = 0, b = 0;
    if (request.low) {
      a = *request.low;
      b = *request.high;
      // Widen by whole steps to hold every value (anchored on the standard range's boundaries) when asked.
      if (request.widen_to_data && has_data && lo < a) a -= step * std::ceil((a - lo) / step - 1e-9);
      if (request.widen_to_data && has_data && hi > b) b += step * std::ceil((hi - b) / step - 1e-9);
    } else {
      if (!has_data) lo = 0, hi = 0;
      a = step * std::floor(lo / step + 1e-9);
      b = step * std::ceil(hi / step - 1e-9);
      if (b <= a) b = a + step;
      const int missing = kMinAbsoluteSteps - static_cast<int>(std::lround((b - a) / step));
      if (missing > 0) {
        a -= step * (missing / 2);
        b += step * (missing - missing / 2);
      }
    }
    out.value_min = a;
    out.value_max = b;
    out.contour_step = step;
    out.label = fmt::format("absolute scale, {:.{}f} {} steps", step, Decimals(step), unit);
    return out;
  }
  if (!has_data) lo = 0, hi = request.symmetric_about_zero ? 0 : 1;
  if (request.symmetric_about_zero) {
    const double m = std::max({std::abs(lo), std::abs(hi), 0.5 * request.min_span});
    const double half = m > 0 ? m : 0.5;
    const double tick = NiceStep(2 * half, 8.0);
    out.value_max = tick * std::ceil(half / tick - 1e-9);
    out.value_min = -out.value_max;
    out.contour_step = NiceStep(out.value_max - out.value_min, 10.0);
    out.label = fmt::format("normalised, symmetric about 0: {} range{}", set_word,
                            2 * std::max(std::abs(lo), std::abs(hi)) < request.min_span
                                ? fmt::format(", min. span {} {}", request.min_span, unit)
                                : std::string());
    return out;
  }
  double span = hi - lo;
  const bool widened = span < request.min_span;
  if (widened) {
    const double mid = 0.5 * (lo + hi);
    lo = mid - 0.5 * request.min_span;
    hi = mid + 0.5 * request.min_span;
    span = request.min_span;
  }
  if (!(span > 0)) {  // a flat field with no minimum span: a unit-wide range around it, as RenderMap does
    lo -= 0.5;
    hi += 0.5;
  }
  const double tick = NiceStep(hi - lo, 8.0);
  out.value_min = tick * std::floor(lo / tick + 1e-9);
  out.value_max = tick * std::ceil(hi / tick - 1e-9);
  out.contour_step = NiceStep(out.value_max - out.value_min, 10.0);
  out.label = fmt::format("normalised: {} range{}", set_word,
                          widened ? fmt::format(", min. span {} {}", request.min_span, unit) : std::string());
  return out;
}

void ApplyMapScale(const MapScale& scale, MapImageOptions* options) {
  options->value_min = scale.value_min;
  options->value_max = scale.value_max;
  options->contour_step = scale.contour_step;
  options->stepped_palette = true;
  options->scale_label = scale.label;
}

}  // namespace topocal::plot

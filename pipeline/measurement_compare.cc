#include "pipeline/measurement_compare.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "pipeline/measurement_uncertainty.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

using nlohmann::json;

struct Compared {
  const char* key;
  const char* label;
  bool axis;  // an axis in degrees: the change wraps at 180
};
constexpr Compared kCompared[] = {
    {"clinical.sim_k.steep_D", "sim-K steep", false},
    {"clinical.sim_k.flat_D", "sim-K flat", false},
    {"clinical.sim_k.cylinder_D", "corneal cylinder", false},
    {"clinical.sim_k.steep_axis_deg", "steep axis", true},
    {"clinical.kmax.power_D", "Kmax", false},
    {"clinical.kmax.x_mm", "Kmax location x", false},
    {"clinical.kmax.y_mm", "Kmax location y", false},
    {"clinical.best_fit_sphere.radius_mm", "best-fit sphere radius", false},
    {"clinical.best_fit_sphere.elevation_peak_um", "elevation peak", false},
    {"clinical.inferior_superior_D", "I-S", false},
    {"power.central_axial_D", "central axial power", false},
    {"surface_fit.rx_mm", "r_x", false},
    {"surface_fit.ry_mm", "r_y", false},
    {"surface_fit.kx", "k_x", false},
    {"surface_fit.ky", "k_y", false},
};

// The document's quantities with their U, after checking that it is a measurement that may be compared.
const json& QuantitiesOf(const json& doc, const std::string& name) {
  if (!doc.is_object()) throw util::InputError(fmt::format("{}: not a reconstruct --json document", name));
  const auto valid = doc.find("valid");
  if (valid == doc.end() || !valid->is_boolean()) {
    throw util::InputError(fmt::format("{}: valid: missing (not a reconstruct --json document)", name));
  }
  if (!valid->get<bool>()) {
    throw util::InputError(fmt::format("{}: valid is false: the measurement was refused, there is nothing to compare",
                                       name));
  }
  const auto u = doc.find("uncertainty");
  if (u == doc.end() || !u->is_object() || !u->contains("quantities") || !(*u)["quantities"].is_object()) {
    throw util::InputError(fmt::format("{}: uncertainty.quantities: missing: measure with --image and --device (or "
                                       "--calibration) so that every number carries its U",
                                       name));
  }
  return (*u)["quantities"];
}

struct Reading {
  double value = 0, U = 0;
  bool determined = true, lower_bound = false;
  std::string unit;
};

// One quantity of one document; the reason it cannot be compared otherwise.
std::optional<Reading> ReadingOf(const json& quantities, const char* key, const std::string& name, std::string* why) {
  const auto q = quantities.find(key);
  if (q == quantities.end() || !q->is_object()) {
    *why = fmt::format("not in {}", name);
    return std::nullopt;
  }
  const auto number = [&](const char* field) -> std::optional<double> {
    const auto f = q->find(field);
    if (f == q->end() || !f->is_number() || !std::isfinite(f->get<double>())) return std::nullopt;
    return f->get<double>();
  };
  const auto value = number("value"), U = number("expanded");
  if (!value || !U || *U < 0) {
    *why = fmt::format("{} holds no value with a U", name);
    return std::nullopt;
  }
  // Flags and unit as reconstruct writes them; anything else reads as the cautious default.
  const auto flag = [&](const char* field, bool fallback) {
    const auto f = q->find(field);
    return f != q->end() && f->is_boolean() ? f->get<bool>() : fallback;
  };
  const auto unit = q->find("unit");
  Reading r{*value, *U, flag("determined", false), flag("lower_bound", true),
            unit != q->end() && unit->is_string() ? unit->get<std::string>() : ""};
  if (!r.determined) *why = fmt::format("not determined by the data of {}", name);
  if (r.lower_bound) *why = fmt::format("its U is only a lower bound in {}", name);
  return r;
}

QuantityChange Compare(const Compared& c, const json& qa, const std::string& a_name, const json& qb,
                       const std::string& b_name) {
  QuantityChange out{c.key, c.label, "", std::nullopt, std::nullopt, std::nullopt, std::nullopt, false, ""};
  std::string why_a, why_b;
  const auto a = ReadingOf(qa, c.key, a_name, &why_a);
  const auto b = ReadingOf(qb, c.key, b_name, &why_b);
  if (a) out.a = a->value, out.unit = a->unit;
  if (b) out.b = b->value, out.unit = b->unit;
  if (!why_a.empty() || !why_b.empty()) {
    out.not_compared = why_a.empty() ? why_b : why_a;
    return out;
  }
  double change = b->value - a->value;
  if (c.axis) change = std::remainder(change, 180.0);  // in [-90, 90]
  out.change = change;
  out.change_U = std::hypot(a->U, b->U);
  out.changed = std::abs(change) > *out.change_U;
  return out;
}

}  // namespace

MeasurementComparison CompareMeasurements(const json& a, const std::string& a_name, const json& b,
                                          const std::string& b_name) {
  const json& qa = QuantitiesOf(a, a_name);
  const json& qb = QuantitiesOf(b, b_name);
  const auto eye = [](const json& doc, const std::string& name) {
    const auto e = doc.find("eye");
    if (e == doc.end()) return std::string();
    if (!e->is_string()) throw util::InputError(fmt::format("{}: eye: not a string", name));
    return e->get<std::string>();
  };
  const std::string eye_a = eye(a, a_name), eye_b = eye(b, b_name);
  if (!eye_a.empty() && !eye_b.empty() && eye_a != eye_b) {
    throw util::InputError(fmt::format("{}: eye {} and {}: eye {}: not the same eye", a_name, eye_a, b_name, eye_b));
  }
  MeasurementComparison out;
  out.eye = eye_a.empty() ? eye_b : eye_a;
  for (const Compared& c : kCompared) out.quantities.push_back(Compare(c, qa, a_name, qb, b_name));
  return out;
}

namespace {

// The maps reconstruct --maps writes that are compared, their change's title and scale step.
struct MapKind {
  const char* stem;
  const char* title;
  double step;  // the change scale's step, in the map's unit
};
constexpr MapKind kMapKinds[] = {{"axial_power", "Axial power change, B - A", 0.25},
                                 {"tangential_power", "Tangential power change, B - A", 0.25},
                                 {"elevation", "Elevation change, B - A", 1.0}};
// The change scales: fixed steps, symmetric about 0 over 10 steps each side (+-2.5 D, +-10 um), widened by whole
// steps to hold larger changes; so two comparisons' maps read alike.
constexpr int kChangeStepsEachSide = 10;

model::GridMap ReadPair(const std::string& dir, const char* stem) {
  return plot::ReadMapCsv((std::filesystem::path(dir) / (std::string(stem) + ".csv")).string());
}

// The map's value at (x, y) mm, bilinear between its four neighbouring samples; NaN outside the grid or where a
// neighbour has no data.
double SampleAt(const model::GridMap& m, double x, double y) {
  const double fi = (x - m.x_min_mm) / (m.x_max_mm - m.x_min_mm) * (m.nx - 1);
  const double fj = (y - m.y_min_mm) / (m.y_max_mm - m.y_min_mm) * (m.ny - 1);
  constexpr double kEdge = 1e-9;  // a sample on the grid's edge is inside it
  if (!(fi >= -kEdge && fj >= -kEdge && fi <= m.nx - 1 + kEdge && fj <= m.ny - 1 + kEdge)) return std::nan("");
  const int i = std::clamp(static_cast<int>(std::floor(fi)), 0, m.nx - 2);
  const int j = std::clamp(static_cast<int>(std::floor(fj)), 0, m.ny - 2);
  const double tx = std::clamp(fi - i, 0.0, 1.0), ty = std::clamp(fj - j, 0.0, 1.0);
  return (1 - ty) * ((1 - tx) * m.At(i, j) + tx * m.At(i + 1, j)) + ty * ((1 - tx) * m.At(i, j + 1) + tx * m.At(i + 1, j + 1));
}

// `b` on the grid of `a` (the measurements' maps may cover different discs: each is drawn to its own data). Throws
// util::InputError naming b_file when the units differ.
model::GridMap OnGridOf(const model::GridMap& a, const model::GridMap& b, const std::string& b_file) {
  if (a.unit != b.unit) {
    throw util::InputError(fmt::format("{}: in {}, its counterpart in {}", b_file, b.unit, a.unit));
  }
  model::GridMap out = a;
  for (int j = 0; j < a.ny; ++j) {
    const double y = a.y_min_mm + j * (a.y_max_mm - a.y_min_mm) / (a.ny - 1);
    for (int i = 0; i < a.nx; ++i) {
      const double x = a.x_min_mm + i * (a.x_max_mm - a.x_min_mm) / (a.nx - 1);
      out.values[static_cast<size_t>(j) * a.nx + i] = SampleAt(b, x, y);
    }
  }
  return out;
}

// A fixed scale of `step` over [low, high] steps, widened by whole steps to hold the data.
plot::MapScale FixedScale(const std::vector<const model::GridMap*>& maps, double step, int low_steps, int high_steps) {
  plot::MapScaleRequest r;
  r.kind = plot::MapScaleKind::kAbsolute;
  r.step = step;
  r.low = low_steps * step;
  r.high = high_steps * step;
  r.widen_to_data = true;
  return plot::SelectMapScale(maps, r);
}

}  // namespace

MapComparison CompareMapDirectories(const std::string& a_dir, const std::string& b_dir) {
  MapComparison out;
  for (const MapKind& kind : kMapKinds) {
    const model::GridMap a = ReadPair(a_dir, kind.stem);
    const model::GridMap b =
        OnGridOf(a, ReadPair(b_dir, kind.stem), (std::filesystem::path(b_dir) / (std::string(kind.stem) + ".csv")).string());
    MapChange c;
    c.name = std::string(kind.stem) + "_change";
    c.map = a;
    c.map.title = kind.title;
    for (size_t k = 0; k < a.values.size(); ++k) c.map.values[k] = b.values[k] - a.values[k];  // NaN where either is
    c.scale = FixedScale({&c.map}, kind.step, -kChangeStepsEachSide, kChangeStepsEachSide);
    out.maps.push_back(std::move(c));
  }
  const auto ua_file = std::filesystem::path(a_dir) / "axial_uncertainty.csv";
  const auto ub_file = std::filesystem::path(b_dir) / "axial_uncertainty.csv";
  if (std::filesystem::exists(ua_file) && std::filesystem::exists(ub_file)) {
    const model::GridMap& axial = out.maps.front().map;
    const model::GridMap ua = OnGridOf(axial, plot::ReadMapCsv(ua_file.string()), ua_file.string());
    const model::GridMap ub = OnGridOf(axial, plot::ReadMapCsv(ub_file.string()), ub_file.string());
    MapChange u;
    u.name = "axial_change_uncertainty";
    u.map = ua;
    u.map.unit = "D";
    u.map.title = "U of the axial power change (k = 2)";
    int compared = 0, beyond = 0;
    double largest = 0;
    for (size_t k = 0; k < ua.values.size(); ++k) {
      u.map.values[k] = std::hypot(ua.values[k], ub.values[k]);
      const double change = axial.values[k];
      if (!std::isfinite(change) || !std::isfinite(u.map.values[k])) continue;
      ++compared;
      if (std::abs(change) > u.map.values[k]) {
        ++beyond;
        largest = std::max(largest, std::abs(change));
      }
    }
    u.scale = FixedScale({&u.map}, 0.05, 0, 10);  // 0-0.5 D in 0.05 D steps, as reconstruct's U map
    if (compared > 0) {
      out.axial_fraction_beyond_U = static_cast<double>(beyond) / compared;
      out.axial_largest_beyond_U_D = largest;
      out.maps.front().annotations.push_back(
          fmt::format("|change| > U over {:.1f} % of the compared disc", 100.0 * beyond / compared));
    }
    out.maps.push_back(std::move(u));
  }
  return out;
}

void WriteMapComparison(const std::string& dir, const MapComparison& comparison, const std::string& eye) {
  for (const MapChange& c : comparison.maps) {
    const std::string path = (std::filesystem::path(dir) / c.name).string();
    plot::WriteMapCsv(path + ".csv", c.map);
    plot::MapImageOptions o;
    plot::ApplyMapScale(c.scale, &o);
    o.annotations = c.annotations;
    o.eye = eye;
    plot::WriteMapPng(path + ".png", c.map, o);
  }
}

json ComparisonJson(const MeasurementComparison& c, const std::optional<MapComparison>& maps) {
  json q = json::array();
  for (const QuantityChange& x : c.quantities) {
    const auto opt = [](const std::optional<double>& v) { return v ? json(*v) : json(nullptr); };
    json e = {{"key", x.key}, {"label", x.label}, {"unit", x.unit}, {"a", opt(x.a)}, {"b", opt(x.b)}};
    if (x.change) {
      e["change"] = *x.change;
      e["change_expanded"] = *x.change_U;
      e["verdict"] = x.changed ? "beyond U" : "within U";
    } else {
      e["verdict"] = "not compared";
      e["reason"] = x.not_compared;
    }
    q.push_back(e);
  }
  json out = {{"format", "topocal-comparison"},
              {"format_version", 1},
              {"coverage_factor", 2},
              {"change", "B - A"},
              {"change_expanded", "sqrt(U_A^2 + U_B^2): the two measurements independent"},
              {"quantities", q}};
  if (!c.eye.empty()) out["eye"] = c.eye;
  if (maps) {
    json m = json::array();
    for (const MapChange& mc : maps->maps) m.push_back(mc.name);
    out["maps"] = m;
    if (maps->axial_fraction_beyond_U) {
      out["axial_fraction_beyond_U"] = *maps->axial_fraction_beyond_U;
      out["axial_largest_change_beyond_U_D"] = *maps->axial_largest_beyond_U_D;
    }
  }
  return out;
}

std::vector<std::string> ComparisonLines(const MeasurementComparison& c, const std::optional<MapComparison>& maps) {
  std::vector<std::string> lines;
  lines.push_back(fmt::format("change B - A{} (U of the change, k = 2: sqrt(U_A^2 + U_B^2), the two measurements "
                              "independent)",
                              c.eye.empty() ? "" : ", eye " + c.eye));
  int changed = 0, within = 0;
  for (const QuantityChange& x : c.quantities) {
    const std::string unit = x.unit.empty() ? "" : " " + x.unit;
    if (!x.change) {
      lines.push_back(fmt::format("  {:<24} not compared: {}", x.label, x.not_compared));
      continue;
    }
    (x.changed ? changed : within) += 1;
    lines.push_back(fmt::format("  {:<24} {}{}  {}", x.label,
                                (*x.change >= 0 ? "+" : "") + FormatWithUncertainty(*x.change, *x.change_U), unit,
                                x.changed ? "BEYOND U: changed" : "within U: no change shown"));
  }
  if (maps && maps->axial_fraction_beyond_U) {
    lines.push_back(fmt::format("axial map: |change| > U over {:.1f} % of the compared disc{}",
                                100 * *maps->axial_fraction_beyond_U,
                                *maps->axial_fraction_beyond_U > 0
                                    ? fmt::format(" (largest {:.3g} D)", *maps->axial_largest_beyond_U_D)
                                    : std::string()));
  }
  lines.push_back(changed == 0 ? fmt::format("no number changed beyond its U ({} compared)", within)
                               : fmt::format("{} of {} compared numbers changed beyond their U (at k = 2 about 1 in 20 "
                                             "numbers of an unchanged eye lands beyond U)",
                                             changed, changed + within));
  return lines;
}

}  // namespace topocal::pipeline

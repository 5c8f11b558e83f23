#pragma once
// `topocal compare`: two measurements of one eye (or of one test surface through two calibrations), as
// `reconstruct --json` wrote them, and optionally their `--maps` directories (docs/compare.md).
//
// Each clinical number's change B - A with the U of the change, U = sqrt(U_A^2 + U_B^2) (k = 2; the two
// measurements independent: two captures, each with its own spot noise and, through a device, its own device
// covariance draw — for two measurements through the same device file the device part is shared and this U is an
// upper bound). A change is stated only where both numbers carry a U the data determine: "within U" when
// |change| <= U (no change shown), "beyond U" when beyond; otherwise the reason it is not compared. Axes wrap at 180 deg.
//
// The maps: the change of the axial and tangential power and of the elevation, on A's grid (B resampled bilinearly:
// each measurement maps its own disc), on fixed stated scales (0.25 D and 1 um steps, symmetric about 0), and with
// both axial U maps the U of the axial change and the part of the disc where |change| > U.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "plot/map_image.h"

namespace topocal::pipeline {

struct QuantityChange {
  std::string key;    // the reconstruct JSON's uncertainty.quantities key, e.g. "clinical.kmax.power_D"
  std::string label;  // e.g. "Kmax"
  std::string unit;
  std::optional<double> a, b, change, change_U;  // absent when not compared
  bool changed = false;                           // |change| > change_U
  std::string not_compared;                       // the reason, when not compared
};

struct MeasurementComparison {
  std::string eye;  // "OD", "OS" or empty
  std::vector<QuantityChange> quantities;
};

// Compares two reconstruct --json documents (named a_name, b_name in messages). Throws util::InputError naming the
// file when a document is not a valid measurement (valid false, no uncertainty block: reconstruct it with --device
// or --calibration and --image) or the two are of different eyes.
MeasurementComparison CompareMeasurements(const nlohmann::json& a, const std::string& a_name, const nlohmann::json& b,
                                          const std::string& b_name);

// One change map and what it shows.
struct MapChange {
  std::string name;  // file stem: axial_power_change, tangential_power_change, elevation_change,
                     // axial_change_uncertainty
  model::GridMap map;
  plot::MapScale scale;
  std::vector<std::string> annotations;
};
struct MapComparison {
  std::vector<MapChange> maps;
  // With both axial U maps: the part of the compared disc (samples with data in A, B and both U maps) where
  // |axial change| > its U, and the largest |change| there (0 when none).
  std::optional<double> axial_fraction_beyond_U, axial_largest_beyond_U_D;
};

// The change maps from two `reconstruct --maps` directories. Throws util::InputError naming the file when a map is
// missing, unreadable or on another grid than its counterpart.
MapComparison CompareMapDirectories(const std::string& a_dir, const std::string& b_dir);

// Writes the change maps (CSV and PNG) into dir; `eye` ("OD", "OS" or empty) labels them as the measurements' maps.
void WriteMapComparison(const std::string& dir, const MapComparison& comparison, const std::string& eye);

// The comparison as JSON (compare --json), and as the lines the command prints.
nlohmann::json ComparisonJson(const MeasurementComparison& c, const std::optional<MapComparison>& maps);
std::vector<std::string> ComparisonLines(const MeasurementComparison& c, const std::optional<MapComparison>& maps);

}  // namespace topocal::pipeline

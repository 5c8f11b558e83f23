#pragma once
// The fleet report (docs/fleet.md): the production line as a whole from the fleet database - per-parameter
// distributions, Shewhart individuals charts with Western Electric run rules over time for the whole line and per
// station (limits from the data, report/control_chart.h), each unit's verdict against the limits, the units out of
// control and those near or beyond their acceptance limits; as one self-contained HTML page, CSV and JSON.
// Deterministic: the same database content and limits give the same bytes.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "report/acceptance.h"
#include "report/control_chart.h"
#include "report/fleet_db.h"

namespace topocal::report {

inline constexpr const char* kFleetReportFormat = "topocal-fleet-report";
inline constexpr int kFleetReportFormatVersion = 1;
// A passing unit whose |value| + U (guarded) or |value| (simple) uses at least this fraction of its limit is listed
// as near its limit: a fifth of the tolerance left is where a line engineer starts to look.
inline constexpr double kNearLimitFraction = 0.8;

// A charted parameter: its label and unit, and the limit that judges it (none for the calibration parameters).
struct FleetParameter {
  std::string key, label, unit;
  std::optional<double> limit;
  bool uses_U = false;     // judged with the guarded rule's U
  bool one_sided = false;  // the limit is a maximum of a non-negative value (RMS), not +-limit
};

struct ChartSeries {
  std::string parameter, station;  // station "" = the whole line
  std::vector<std::size_t> units;  // indices into FleetAnalysis::units, time order
  std::vector<double> values;
  std::optional<ControlChart> chart;  // limits from the passing units only (phase I)
  std::optional<Capability> capability;  // of the values against the parameter's limit, when it has one
};

struct UnitVerdict {
  bool pass = false;
  std::vector<std::string> failed;  // parameters beyond their limit (or missing: "not verified")
  std::vector<std::string> near;    // parameters within kNearLimitFraction of it
};

struct OutOfControl {
  std::size_t unit = 0;
  std::string parameter, station;  // station "" = on the whole line's chart
  std::vector<int> rules;
};

struct FleetAnalysis {
  std::string database;
  Limits limits;
  std::vector<FleetUnit> units;
  std::vector<FleetParameter> parameters;
  std::vector<std::string> stations;
  std::vector<ChartSeries> series;  // per parameter: the line, then each station
  std::vector<UnitVerdict> verdicts;
  std::vector<OutOfControl> out_of_control;
};

FleetAnalysis AnalyseFleet(const std::string& database, std::vector<FleetUnit> units, const Limits& limits);

std::string RenderFleetHtml(const FleetAnalysis& analysis);
// One row per unit and parameter: serial,unit_json_sha256,created_utc,station,parameter,value,U,limit,unit_verdict.
std::string FleetCsv(const FleetAnalysis& analysis);
nlohmann::json FleetJson(const FleetAnalysis& analysis);

}  // namespace topocal::report

#pragma once
// The analysis behind the fleet report (docs/fleet.md): each unit's verdict against the limits, the counts per
// station, and per parameter the control charts of the whole line and of each station (report/control_chart.h),
// built from the units given one at a time in time order (FleetAnalyser), so that a fleet of any size is analysed in
// bounded memory: a chart never holds more than kMaxChartPoints points, and only the units the report lists are
// kept.
//
// A series of up to kMaxChartPoints units is an individuals chart, one point per unit. A longer one is a chart of
// subgroup means: consecutive units in groups of m = 2, 4, 8, ... (the smallest power of two that keeps the points
// within kMaxChartPoints; the last group may be smaller), each point the mean of its group's passing units.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "plot/svg_charts.h"
#include "report/acceptance.h"
#include "report/control_chart.h"
#include "report/fleet_db.h"

namespace topocal::report {

// A passing unit whose |value| + U (guarded) or |value| (simple) uses at least this fraction of its limit is listed
// as near its limit: a fifth of the tolerance left is where a line engineer starts to look.
inline constexpr double kNearLimitFraction = 0.8;
// The most points a control chart holds (and draws): more than its width in the report can show apart.
inline constexpr int kMaxChartPoints = 200;
// The units the report keeps to list by name: every unit of a fleet up to kMaxListedUnits (the report's unit
// table); beyond it, the FAIL units and those near a limit, each list up to kMaxListedUnits (the CSV has every unit).
inline constexpr std::size_t kMaxListedUnits = 1000;

// A charted parameter: its label and unit, and the limit that judges it (none for the calibration parameters).
struct FleetParameter {
  std::string key, label, unit;
  std::optional<double> limit;
  bool uses_U = false;     // judged with the guarded rule's U
  bool one_sided = false;  // the limit is a maximum of a non-negative value (RMS), not +-limit
};

// One point of a chart: a unit, or a subgroup of consecutive units.
struct ChartPoint {
  double value = 0;  // the unit's value, or the subgroup's mean (of its passing units; of all when none passed)
  int units = 1;
  std::string first_serial, last_serial, first_utc, last_utc, first_sha256;
  std::optional<std::size_t> unit;  // index into FleetAnalysis::units (a point of one unit)
};

struct ChartSeries {
  std::string parameter, station;  // station "" = the whole line
  std::vector<ChartPoint> points;  // time order
  int subgroup_size = 1;           // units per point (the last point may hold fewer)
  std::int64_t n = 0;              // units
  double mean = 0, sd = 0;         // of every unit's value
  std::optional<ControlChart> chart;     // limits from the passing units only (phase I)
  std::optional<Capability> capability;  // of the values against the parameter's limit, when it has one
  std::optional<plot::HistogramBins> histogram;  // the whole line's series: every unit's value
  std::vector<double> Values() const;
};

struct UnitVerdict {
  bool pass = false;
  std::vector<std::string> failed;  // parameters beyond their limit (or missing: "not verified")
  std::vector<std::string> near;    // parameters within kNearLimitFraction of it
};

struct OutOfControl {
  ChartPoint point;
  std::string parameter, station;  // station "" = on the whole line's chart
  std::vector<int> rules;
};

struct StationCount {
  std::string station;  // "" = the whole line
  std::int64_t units = 0, passed = 0, near = 0;
};

struct FleetAnalysis {
  std::string database;
  Limits limits;
  std::int64_t unit_count = 0, serial_count = 0;
  std::string first_utc, last_utc;
  std::vector<FleetUnit> units;  // the units kept to be listed, in time order (every one when units_complete)
  std::vector<UnitVerdict> verdicts;  // of `units`
  bool units_complete = true;
  std::int64_t failed_not_listed = 0, near_not_listed = 0;  // beyond kMaxListedUnits
  std::vector<FleetParameter> parameters;
  std::vector<std::string> stations;
  std::vector<StationCount> counts;  // each station, then the whole line
  std::vector<ChartSeries> series;   // per parameter: the line, then each station (when there are several)
  std::vector<OutOfControl> out_of_control;
};

// The parameters judged by a limit, in the order shown, then the device's and the calibration's own (no limit),
// of those among `keys`.
std::vector<FleetParameter> FleetParameters(const std::vector<std::string>& keys, const Limits& limits);
// A unit's verdict against the judged parameters.
UnitVerdict JudgeUnit(const FleetUnit& unit, const std::vector<FleetParameter>& parameters, const Limits& limits);

class FleetAnalyser {
 public:
  FleetAnalyser(std::string database, const Limits& limits);
  ~FleetAnalyser();
  FleetAnalyser(const FleetAnalyser&) = delete;
  FleetAnalyser& operator=(const FleetAnalyser&) = delete;
  // The next unit in time order (created_utc, then id).
  void Add(FleetUnit unit);
  // The charts' limits and signals; the line's histograms from the values when every unit was kept (else the
  // caller gives them: FleetDb::Histogram). serial_count is counted from the kept units when all were kept.
  FleetAnalysis Finish();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// The analysis of units already in memory, in time order (a small fleet, the tests).
FleetAnalysis AnalyseFleet(const std::string& database, std::vector<FleetUnit> units, const Limits& limits);

}  // namespace topocal::report

#pragma once
// The fleet report (docs/fleet.md): the production line as a whole from the fleet database - per-parameter
// distributions, Shewhart individuals charts with Western Electric run rules over time for the whole line and per
// station (limits from the data, report/control_chart.h), each unit's verdict against the limits, the units out of
// control and those near or beyond their acceptance limits; as one self-contained HTML page, CSV and JSON.
// Deterministic: the same database content and limits give the same bytes.
#include <string>

#include <nlohmann/json.hpp>

#include "report/fleet_analysis.h"

namespace topocal::report {

inline constexpr const char* kFleetReportFormat = "topocal-fleet-report";
// 2: charts of subgroup means beyond kMaxChartPoints units (subgroup_size, units per point, the signals of a
// subgroup by its first and last serial); `units` lists every unit up to kMaxListedUnits, else the listed ones
// (units_complete false; the CSV has every unit).
inline constexpr int kFleetReportFormatVersion = 2;

std::string RenderFleetHtml(const FleetAnalysis& analysis);
// One row per unit and parameter: serial,unit_json_sha256,created_utc,station,parameter,value,U,limit,unit_verdict
// (FleetCsvHeader, then FleetCsvRows of each unit in time order: the command line streams every unit of the
// database; FleetCsv writes the analysis's units).
std::string FleetCsvHeader();
std::string FleetCsvRows(const std::vector<FleetParameter>& parameters, const FleetUnit& unit, const UnitVerdict& verdict);
std::string FleetCsv(const FleetAnalysis& analysis);
nlohmann::json FleetJson(const FleetAnalysis& analysis);

}  // namespace topocal::report

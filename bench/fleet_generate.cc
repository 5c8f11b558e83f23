// A production line at scale for the fleet view (docs/fleet.md, "At scale"): `--units` unit records over several
// stations and years, one station's reference-sphere radius error drifting over the last quarter, a few units
// failing, written through the project's record writer (report/unit_record_writer.h) as full records that `topocal
// fleet ingest` reads and verifies like any other (unit.json, calibration.yaml, residuals.csv: everything ingestion
// reads; the PNG maps, which it does not read, are left out). Seeded: the same options give the same records (the
// calibration is one real single-view Seidel calibration, k1 and the residuals scaled per unit;
// tests/report/fleet_fixture.h GenerateFleet).
//
//   build/bench/fleet_generate --units 100000 --out /tmp/fleet-1e5 [--stations 4] [--years 3] [--seed 1]
//       [--fail-fraction 0.005]
// writes OUT/LINE-k/YYYY-MM/SN-000001/ ... and prints the count per station.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <exception>
#include <filesystem>
#include <map>

#include "tests/report/fleet_fixture.h"

int main(int argc, char** argv) {
  using namespace topocal::report::testing;
  CLI::App app{"Write a generated production line of unit records (bench: the fleet at scale)"};
  FleetSpec spec;
  std::string out;
  app.add_option("--out", out, "Directory to create (must not exist)")->required();
  app.add_option("--units", spec.units, "Unit records")->capture_default_str()->check(CLI::Range(1, 10000000));
  app.add_option("--stations", spec.stations, "Calibration stations")->capture_default_str()->check(CLI::Range(1, 99));
  app.add_option("--years", spec.years, "Years the line spans")->capture_default_str()->check(CLI::Range(0.01, 50.0));
  app.add_option("--seed", spec.seed, "Seed of every draw")->capture_default_str();
  app.add_option("--fail-fraction", spec.fail_fraction, "Fraction of units beyond the sphere radius limit")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  CLI11_PARSE(app, argc, argv);
  try {
    if (std::filesystem::exists(out)) throw std::runtime_error(out + ": exists (give a new directory)");
    if (spec.drift_station >= spec.stations) spec.drift_station = spec.stations - 1;
    const auto calibration = FixtureCalibration();
    std::map<std::string, int> per_station;
    int fails = 0;
    for (const FleetLineUnit& f : GenerateFleet(spec)) {
      WriteLineUnit(FleetRecordDir(out, f), calibration, f.unit);
      ++per_station[FleetStationName(f.station)];
      fails += f.fails ? 1 : 0;
    }
    for (const auto& [station, n] : per_station) fmt::print("{}: {} records in {}/{}/\n", station, n, out, station);
    fmt::print("{} records, {} generated to fail, station {} drifting\n", spec.units, fails,
               FleetStationName(spec.drift_station));
  } catch (const std::exception& e) {
    fmt::print(stderr, "fleet_generate: {}\n", e.what());
    return 2;
  }
  return 0;
}

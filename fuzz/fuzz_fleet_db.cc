// Fuzz target: a fleet database file (report/fleet_db.h) and everything `topocal fleet report` and `fleet check` do
// with it. The input is the database's bytes: opening runs SQLite's quick check and compares the layout before
// anything is read; a file that passes goes through Units(), the fleet analysis and its HTML/CSV/JSON renderings
// (every plot helper bounded whatever the stored values), Check() and Backup(). Damage, another layout or a value
// the schema does not allow must end as util::InputError.
#include <filesystem>

#include "fuzz/fuzz_input.h"
#include "report/acceptance.h"
#include "report/fleet_db.h"
#include "report/fleet_report.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace fs = std::filesystem;
  const std::string path = topocal::fuzz::InputFile("fleet.sqlite", data, size);
  // SQLite's journal of an earlier input must not be replayed into this one.
  for (const char* suffix : {"-journal", "-wal", "-shm"}) fs::remove(path + suffix);
  try {
    const topocal::report::FleetDb db(path, false);
    const auto analysis = topocal::report::AnalyseFleet(path, db.Units(), topocal::report::DefaultLimits());
    (void)topocal::report::RenderFleetHtml(analysis);
    (void)topocal::report::FleetCsv(analysis);
    (void)topocal::report::FleetJson(analysis).dump(2);
    (void)db.Check();
    (void)db.Backup();
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}

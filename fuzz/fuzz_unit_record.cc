// Fuzz target: unit.json of a unit record (report/unit_record_reader.h). The record's other files are absent, so
// an input that passes every check of unit.json ends at "missing file": the reader must get there without a crash.
#include <filesystem>

#include "fuzz/fuzz_input.h"
#include "report/unit_record_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto dir = topocal::fuzz::ScratchDir() / "record";
  std::filesystem::create_directories(dir);
  topocal::util::WriteFileAtomic((dir / "unit.json").string(), topocal::fuzz::Text(data, size));
  try {
    topocal::report::ReadUnitRecord(dir.string());
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}

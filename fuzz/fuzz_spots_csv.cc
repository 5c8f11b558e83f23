// Fuzz target: the spots CSV (tools/csv.h, `ring,index,x_mm,y_mm`).
#include "fuzz/fuzz_input.h"
#include "tools/csv.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    topocal::tools::ReadSpotsCsv(topocal::fuzz::InputFile("spots.csv", data, size));
  } catch (const topocal::model::InputError&) {
  }
  return 0;
}

// Fuzz target: the spots CSV (model/spots_csv.h, `ring,index,x_mm,y_mm`).
#include "fuzz/fuzz_input.h"
#include "model/spots_csv.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    topocal::model::ReadSpotsCsv(topocal::fuzz::InputFile("spots.csv", data, size));
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}

#pragma once
// The QA report does not take a unit record's numbers on trust. The digests of unit.json's
// `files` prove that the record's files are the ones written with it, but unit.json itself is not digested by
// anything it contains: an edited `rms_px` or radius error would flip a verdict. So every number the verdict uses
// is recomputed from the record's own files before a report is written:
//
//   calibration.rms_px            from residuals.csv (RMS over the inlier corners), and against calibration.yaml
//   verification (sphere)         the check run again (pipeline::VerifyOnReferenceSphere) from sphere_spots.csv
//                                 and calibration.yaml, with the record's configuration, seed and draws
//   paper_cornea                  the simulation run again (pipeline::SimulateThroughCalibratedCamera) from
//                                 calibration.yaml and the record's configuration, seed and draws
//
// and the blocks built from them (report/unit_record_writer.h) must equal unit.json's, number by number. The Monte
// Carlo draws are seeded per draw, so the recomputation gives the same numbers on any number of threads.
#include "report/unit_record_reader.h"

namespace topocal::report {

struct RecordCheckOptions {
  int jobs = 0;  // threads for the Monte Carlo draws (0 = every core); the result does not depend on it
};

// The cheap part, without any Monte Carlo (what `fleet ingest` checks of every record): calibration.rms_px
// recomputed from residuals.csv, and rms_px, every parameter's stddev and the Seidel sigma with its stddev against
// calibration.yaml (the record's digested calibration file). Throws util::InputError naming the key.
void CheckRecordedCalibration(const UnitRecord& record);

// Throws util::InputError "unit.json: KEY: recorded V, recomputed W from FILES" for the first number that does not
// match, and for a record that lacks what the recomputation needs (configuration, sphere_spots.csv). Includes
// CheckRecordedCalibration.
void RecomputeRecordNumbers(const UnitRecord& record, const RecordCheckOptions& options = {});

}  // namespace topocal::report

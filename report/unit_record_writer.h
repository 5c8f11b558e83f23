#pragma once
// Writing a unit record (docs/unit-record.md): the one writer of the format, beside its reader
// (report/unit_record_reader.h). `topocal unit calibrate` writes the unit the workflow computed
// (pipeline/unit_workflow.h) with WriteUnitRecord; the report and fleet tests and the fleet generator fill
// UnitRecordWriter with generated values, through the same staging and commit.
//
// The record is staged in a temporary sibling directory (`<out>.tmp-<pid>-<token>`) and renamed into place only when
// complete: a failed write leaves no record, and an earlier record at `out` untouched until the new one is whole.
// Commit() adds `format`, `format_version`, `tool_version` and `files` (every staged file except unit.json, sorted,
// with its SHA-256) to the body, refuses a non-finite number (nlohmann writes it as null, which a reader would take
// for a missing value) and writes unit.json with two-space indentation.
#include <filesystem>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "pipeline/unit_workflow.h"

namespace topocal::report {

// Is `path` (a directory given as a record) what a killed writer left: a staging folder "NAME.tmp-PID-TOKEN" or a
// record set aside "NAME.old-PID"? `fleet ingest units/*/` skips them with a line; the next writer of NAME removes
// them.
bool IsRecordLeftover(const std::filesystem::path& path);

class UnitRecordWriter {
 public:
  // Takes the record's lock (another run writing the same record now: util::InputError, nothing written), clears
  // what killed runs left beside the record (their staging folders; a record set aside is put back), and creates
  // the staging directory (with `maps/`) under an unpredictable name. Throws util::InputError naming `out` when it
  // cannot. A record already at `out` is refused at the commit, or with keep_history moved to its unit's history
  // (pipeline::RecordHistoryDir) once the new one is in place.
  explicit UnitRecordWriter(std::filesystem::path out, bool keep_history = false);
  ~UnitRecordWriter();  // removes the staging directory unless committed
  UnitRecordWriter(const UnitRecordWriter&) = delete;
  UnitRecordWriter& operator=(const UnitRecordWriter&) = delete;

  // Where the record's files go before the commit (callers may write there directly, e.g. maps/*.png).
  const std::filesystem::path& staging_dir() const { return staging_; }
  // Writes `name` (relative, inside the record) under the staging directory, creating parent directories.
  void WriteFile(const std::string& name, std::string_view bytes) const;
  // Completes and writes unit.json, then moves the record into place. Throws std::runtime_error for a non-finite
  // number (nothing written), util::InputError when the record cannot be put in place.
  void Commit(nlohmann::json body);

 private:
  void Unlock();  // removes the lock file and releases the lock

  std::filesystem::path out_, staging_;
  int lock_fd_ = -1;
  bool keep_history_ = false;
  bool committed_ = false;
};

// unit.json's blocks of the two checks, "verification" (the reference sphere, photographed as `image`) and
// "paper_cornea" (docs/unit-record.md): written here, and built again from the recomputed checks by the report,
// which compares them number by number (report/record_check.h).
nlohmann::json VerificationJson(const pipeline::SphereVerification& sphere, const std::string& image,
                                const pipeline::CheckOptions& check);
nlohmann::json PaperCorneaJson(const pipeline::SimulatedCornea& paper, const pipeline::CheckOptions& check);

// Writes the record of a computed unit to unit.request.out: unit.json (docs/unit-record.md), calibration.yaml,
// residuals.csv, maps/ (the before/after power, elevation and height-error maps of the reference sphere and the
// paper cornea) and, with the device stage, device.json. Staged and committed whole (UnitRecordWriter): on any
// failure nothing is written and an earlier record at `out` is left as it was. Throws std::runtime_error
// "SERIAL: the result is not usable: KEY: not a finite number" for a NaN or infinity, util::InputError when the
// record cannot be written.
void WriteUnitRecord(const pipeline::UnitResult& unit);

}  // namespace topocal::report

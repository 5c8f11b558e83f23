// topocal.read_unit_record and topocal.FleetDb: a unit's record (read and verified, as `topocal report` reads it)
// and the production line's database (as `topocal fleet` ingests and reports it).
#include <fmt/format.h>

#include <limits>

#include "python/src/py_common.h"
#include "report/fleet_db.h"
#include "report/unit_record_reader.h"
#include "util/io.h"

namespace topocal::python {
namespace {

py::dict UnitRecordDict(const std::string& directory) {
  report::UnitRecord record;
  {
    py::gil_scoped_release release;
    record = report::ReadUnitRecord(directory);  // verifies every listed file's SHA-256
  }
  py::list files;
  for (const auto& f : record.files) files.append(py::make_tuple(f.name, f.sha256));
  return py::dict(py::arg("directory") = record.directory, py::arg("serial") = record.serial,
                  py::arg("created_utc") = record.created_utc, py::arg("tool_version") = record.tool_version,
                  py::arg("unit_json_sha256") = record.unit_json_sha256, py::arg("files") = files,
                  py::arg("unit") = ToPython(nlohmann::json::parse(util::ReadFile(record.unit_json_path))));
}

py::dict UnitDict(const report::FleetUnit& u) {
  py::dict measurements;
  for (const auto& [name, m] : u.measurements) {
    measurements[py::str(name)] = py::make_tuple(m.value, m.U ? py::cast(*m.U) : py::none());
  }
  return py::dict(py::arg("id") = u.id, py::arg("serial") = u.serial, py::arg("unit_json_sha256") = u.unit_json_sha256,
                  py::arg("created_utc") = u.created_utc, py::arg("station") = u.station,
                  py::arg("tool_version") = u.tool_version, py::arg("model") = u.model, py::arg("source") = u.source,
                  py::arg("ingested_utc") = u.ingested_utc, py::arg("measurements") = measurements);
}

// One parameter over the fleet, in the database's order (created_utc, then id): NumPy columns.
py::dict ParameterTable(const report::FleetDb& db, const std::string& parameter) {
  std::vector<report::FleetUnit> units;
  {
    py::gil_scoped_release release;
    units = db.Units();
  }
  py::list serials, created, stations;
  std::vector<double> values, us;
  for (const auto& u : units) {
    const auto it = u.measurements.find(parameter);
    if (it == u.measurements.end()) continue;
    serials.append(u.serial);
    created.append(u.created_utc);
    stations.append(u.station);
    values.push_back(it->second.value);
    us.push_back(it->second.U.value_or(std::numeric_limits<double>::quiet_NaN()));
  }
  const py::object np = py::module_::import("numpy");
  return py::dict(py::arg("serial") = np.attr("array")(serials, "object"),
                  py::arg("created_utc") = np.attr("array")(created, "object"),
                  py::arg("station") = np.attr("array")(stations, "object"),
                  py::arg("value") = py::array_t<double>(static_cast<py::ssize_t>(values.size()), values.data()),
                  py::arg("U") = py::array_t<double>(static_cast<py::ssize_t>(us.size()), us.data()));
}

report::IngestResult Ingest(report::FleetDb& db, const std::vector<std::string>& directories,
                            const std::string& station) {
  if (station.empty()) throw util::InputError("station: must not be empty");
  py::gil_scoped_release release;
  // Every record is read and verified before the database is touched: one bad record refuses the batch.
  std::vector<report::UnitRecord> records;
  for (const auto& d : directories) records.push_back(report::ReadUnitRecord(d));
  return db.Ingest(records, station);
}

}  // namespace

void RegisterRecords(py::module_& m) {
  m.def("read_unit_record", &UnitRecordDict, py::arg("directory"),
        "Read and verify a unit record (as `topocal unit calibrate` writes it; docs/unit-record.md): every listed "
        "file's SHA-256 is checked. Returns serial, created_utc, tool_version, unit_json_sha256, files [(name, "
        "sha256)] and `unit`, the unit.json document. Raises InputError naming the file and key when the record "
        "is malformed or a digest differs.");
  py::class_<report::FleetDb>(m, "FleetDb", "The fleet database (SQLite, docs/fleet.md).")
      .def(py::init<const std::string&, bool>(), py::arg("path"), py::arg("create") = false,
           "Open the database; create=True creates it (for ingest). Raises InputError when it is not a topocal "
           "fleet database or cannot be opened.")
      .def(
          "ingest",
          [](report::FleetDb& db, const std::vector<std::string>& directories, const std::string& station) {
            const auto r = Ingest(db, directories, station);
            return py::make_tuple(r.added, r.present);
          },
          py::arg("directories"), py::arg("station"),
          "Verify the unit records and add them in one transaction (all or none). Returns (added, already present).")
      .def(
          "units",
          [](const report::FleetDb& db) {
            std::vector<report::FleetUnit> units;
            {
              py::gil_scoped_release release;
              units = db.Units();
            }
            py::list out;
            for (const auto& u : units) out.append(UnitDict(u));
            return out;
          },
          "Every unit (dicts: serial, station, dates, measurements {parameter: (value, U or None)}), in order of "
          "created_utc.")
      .def("table", &ParameterTable, py::arg("parameter"),
           "One parameter over the fleet as NumPy columns: serial, created_utc, station (object arrays), value and "
           "U (float64, NaN where unknown; expanded, k = 2).")
      .def(
          "check",
          [](const report::FleetDb& db) {
            report::FleetCheck c;
            {
              py::gil_scoped_release release;
              c = db.Check();
            }
            return py::make_tuple(c.units, c.measurements);
          },
          "SQLite's integrity check, the layout and every stored value (`topocal fleet check`). Returns (units, "
          "measurements); raises InputError naming the first finding.")
      .def(
          "backup",
          [](const report::FleetDb& db, const std::string& out) {
            py::gil_scoped_release release;
            util::WriteFileAtomic(out, db.Backup());
          },
          py::arg("out"),
          "A consistent, checked copy of the database written to `out` as one file (`topocal fleet backup`).")
      .def_property_readonly("path", &report::FleetDb::path);
}

}  // namespace topocal::python

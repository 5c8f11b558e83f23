#pragma once
// The pieces of the QA report's page (report/html_report.cc assembles them; docs/report.md shows the page): number
// formatting that never prints "nan" or "-0.000", one function per section, and the comparison with the unit's
// previous calibration that the page and its JSON share.
#include <cmath>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "report/html_report.h"

namespace topocal::report::html {

std::string H(std::string_view s);          // escaped for HTML text and attributes
std::string Fixed(double v, int decimals);  // fixed decimals; a dash for a value that is not finite, never "-0.000"
std::string Sig(double v, int digits = 6);  // significant digits; a dash for a value that is not finite

// One quantity of the unit's previous calibration beside this one (the report's table and its JSON).
struct ComparisonRow {
  std::string id, label, unit;  // label and unit as HTML
  std::string plain_unit;       // the unit in the JSON
  std::optional<double> prev, now, U_prev, U_now;
  int digits;
  // The change, and the U of a difference, sqrt(U_prev^2 + U_now^2) (k = 2, independent calibrations).
  std::optional<double> Change() const { return prev && now ? std::optional(*now - *prev) : std::nullopt; }
  std::optional<double> ChangeU() const {
    return U_prev && U_now ? std::optional(std::hypot(*U_prev, *U_now)) : std::nullopt;
  }
};

// The numbers a service engineer compares between the unit's previous calibration and this one.
std::vector<ComparisonRow> ComparisonRows(const UnitRecord& now, const UnitRecord& prev, const ReportInputs& in);

// The page's sections, in the order they are shown.
std::string IdentitySection(const UnitRecord& rec, const std::string& id);
std::string SignOffSection(const ReportInputs& inputs, const char* verdict_word, const std::string& id);
std::string MethodSection(const UnitRecord& rec, const Limits& limits);
std::string CalibrationSection(const UnitRecord& rec);
std::string ResidualsSection(const UnitRecord& rec, const Limits& limits);
std::string SphereSection(const UnitRecord& rec);
std::string PaperSection(const UnitRecord& rec);
std::string DeviceSection(const UnitRecord& rec);
std::string PreviousComparison(const UnitRecord& now, const UnitRecord& prev, const ReportInputs& in);
std::string AcceptanceSection(const UnitRecord& rec, const Limits& limits, const Verdict& verdict,
                              const char* verdict_word, const std::string& id);
std::string ProvenanceSection(const UnitRecord& rec, const ReportInputs& inputs);

}  // namespace topocal::report::html

#include "report/html_report.h"

#include <fmt/format.h>
#include <openssl/evp.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <tuple>

#include "report/html_parts.h"
#include "util/io.h"
#include "util/sha256.h"
#include "util/version.h"

namespace topocal::report {

using html::ComparisonRow;
using html::ComparisonRows;
using html::H;

namespace {

constexpr const char* kCss = R"css(
:root { --pass: #2e7d32; --fail: #c62828; --ink: #1a1a1a; --rule: #c8c8c8; }
* { box-sizing: border-box; }
html { -webkit-print-color-adjust: exact; print-color-adjust: exact; }
body { font-family: "DejaVu Sans", Arial, sans-serif; color: var(--ink); margin: 0; font-size: 10.5pt; line-height: 1.35; }
main { max-width: 190mm; margin: 0 auto; padding: 8mm 6mm; }
h1 { font-size: 17pt; margin: 0 0 2mm 0; }
h2 { font-size: 13pt; border-bottom: 1.5px solid var(--ink); padding-bottom: 1mm; margin: 7mm 0 3mm 0; }
h3 { font-size: 11pt; margin: 5mm 0 2mm 0; }
table.data { border-collapse: collapse; width: 100%; margin: 2mm 0; }
table.data td { overflow-wrap: break-word; }  /* a token breaks only when it cannot fit a line of its own */
table.data th, table.data td { border-bottom: 1px solid var(--rule); padding: 1mm 2mm; text-align: left; vertical-align: top; }
table.data th { background: #f0f0f0; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
.hash { font-family: "DejaVu Sans Mono", monospace; font-size: 7.5pt; word-break: break-all; }
.banner { font-size: 20pt; font-weight: bold; color: #fff; padding: 4mm 6mm; margin: 3mm 0; border-radius: 2mm; }
.banner.pass { background: var(--pass); }
.banner.fail { background: var(--fail); }
.banner small { display: block; font-size: 10pt; font-weight: normal; }
ul.failed { color: var(--fail); font-weight: bold; margin: 0 0 3mm 0; }
td.pass { color: var(--pass); font-weight: bold; }
td.fail { color: var(--fail); font-weight: bold; }
.report-id { font-family: "DejaVu Sans Mono", monospace; }
.note { color: #555; font-size: 9pt; }
svg.plot { width: 100%; height: auto; display: block; margin: 2mm 0; }
figure { margin: 0; }
.map-row { display: flex; gap: 4mm; margin: 2mm 0; break-inside: avoid; }
.map-row figure { flex: 1 1 0; text-align: center; }
.map-row img { width: 100%; height: auto; border: 1px solid var(--rule); }
.nomap { border: 1px dashed var(--rule); padding: 20mm 2mm; color: #777; }
figcaption { font-size: 9pt; color: #444; }
.keep { break-inside: avoid; }
.print-header, .print-footer { display: none; }
table.page-frame { width: 100%; border-collapse: collapse; }
table.page-frame > thead td, table.page-frame > tfoot td, table.page-frame > tbody > tr > td { padding: 0; }
@page { size: A4; margin: 10mm 10mm 12mm 10mm;
  @bottom-right { content: "Page " counter(page) " of " counter(pages); font-family: "DejaVu Sans", Arial, sans-serif;
                  font-size: 8pt; color: #333; } }
table.budget td, table.budget th { font-size: 9pt; }
.signoff td.blank { height: 11mm; border-bottom: 1px solid var(--ink); }
.undefined { color: #555; font-style: italic; }
td.flag { white-space: nowrap; }
@media print {
  body { font-size: 9.5pt; }
  main { max-width: none; padding: 0; }
  .print-header, .print-footer { display: block; position: fixed; left: 0; right: 0; font-size: 8pt; color: #333;
                                 background: #fff; }
  .print-header { top: 0; border-bottom: 1px solid var(--rule); padding-bottom: 1mm; }
  .print-footer { bottom: 0; border-top: 1px solid var(--rule); padding-top: 1mm; }
  .header-space { height: 9mm; }
  .footer-space { height: 8mm; }
  .page-break { break-before: page; }
  h2, h3 { break-after: avoid; }
  svg.plot, table.data tr, .banner { break-inside: avoid; }
}
)css";


constexpr const char* kImageCheckScript = R"js(
window.addEventListener('load', function () {
  var images = document.images, decoded = 0;
  for (var i = 0; i < images.length; ++i) {
    if (images[i].complete && images[i].naturalWidth > 0) ++decoded;
  }
  document.documentElement.setAttribute('data-images-decoded', decoded + '/' + images.length);
});
)js";

}  // namespace

std::string Base64(std::string_view bytes) {
  if (bytes.empty()) return {};
  // OpenSSL's encoder: EVP_EncodeBlock writes the RFC 4648 alphabet with padding and no line breaks (unlike
  // EVP_EncodeUpdate, which breaks lines every 64 characters), plus a NUL. Its length argument is an int.
  if (bytes.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()) / 4 * 3) {
    throw std::length_error(fmt::format("base64: {} bytes is more than one block can encode", bytes.size()));
  }
  std::string out(4 * ((bytes.size() + 2) / 3) + 1, '\0');
  const int written = EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data()),
                                      reinterpret_cast<const unsigned char*>(bytes.data()), static_cast<int>(bytes.size()));
  out.resize(static_cast<std::size_t>(written));
  return out;
}

void ReportInputs::Validate(const UnitRecord& record) const {
  std::string why;
  if (!budget.IsValid(&why)) throw util::InputError("--ball-radius-U-mm: " + why);
  if (previous && previous->serial != record.serial) {
    throw util::InputError(fmt::format("{}: the previous record is of unit {}, not {}", previous->directory,
                                       previous->serial, record.serial));
  }
  if (previous && previous->unit_json_sha256 == record.unit_json_sha256) {
    throw util::InputError(
        fmt::format("{}: the previous record is the same record as {}", previous->directory, record.directory));
  }
}

std::string ReportIdText(const UnitRecord& record, const ReportInputs& in) {
  const SignOff& so = in.sign_off;
  return fmt::format(
      "topocal-report-id 1\nunit_json_sha256={}\nlimits={}\nball_radius_U_mm={}\noperator={}\nstation={}\n"
      "ball_certificate_id={}\ntarget_certificate_id={}\nprevious_unit_json_sha256={}\n",
      record.unit_json_sha256, CanonicalLimits(in.limits),
      in.budget.ball_radius_U_mm ? fmt::format("{}", *in.budget.ball_radius_U_mm) : std::string("default"),
      so.operator_name, so.station, so.ball_certificate_id, so.target_certificate_id,
      in.previous ? in.previous->unit_json_sha256 : std::string("none"));
}

std::string ReportId(const UnitRecord& record, const ReportInputs& inputs) {
  return record.serial + "-" + util::Sha256Hex(ReportIdText(record, inputs)).substr(0, kReportIdHexDigits);
}
std::string RenderHtmlReport(const UnitRecord& rec, const ReportInputs& inputs) {
  inputs.Validate(rec);
  const Limits& limits = inputs.limits;
  const std::string id = ReportId(rec, inputs);
  const Verdict verdict = Evaluate(rec, limits, inputs.budget);
  const char* verdict_word = verdict.pass ? "PASS" : "FAIL";
  int failed = 0;
  for (const Check& c : verdict.checks) failed += c.pass ? 0 : 1;

  std::string s;
  s += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  s += fmt::format("<meta name=\"report-id\" content=\"{}\">\n", H(id));
  s += fmt::format("<title>topocal QA report {} \u2014 {}</title>\n", H(id), verdict_word);
  s += fmt::format("<style>{}</style>\n</head>\n", kCss);
  s += fmt::format("<body data-report-id=\"{}\" data-verdict=\"{}\">\n", H(id), verdict_word);
  // Repeated on every printed page (position: fixed in @media print); the page-frame table's header and footer
  // rows keep the content clear of them.
  s += fmt::format("<div class=\"print-header\">topocal QA report <span class=\"report-id\">{}</span> \u00b7 unit {} "
                   "\u00b7 {}</div>\n",
                   H(id), H(rec.serial), verdict_word);
  s += fmt::format("<div class=\"print-footer\">Report <span class=\"report-id\">{}</span> \u00b7 record created {} "
                   "\u00b7 topocal {}</div>\n",
                   H(id), H(rec.created_utc), H(kVersion));
  s += "<table class=\"page-frame\"><thead><tr><td><div class=\"header-space\"></div></td></tr></thead>\n"
       "<tfoot><tr><td><div class=\"footer-space\"></div></td></tr></tfoot>\n<tbody><tr><td>\n<main>\n";

  // Title and verdict.
  s += fmt::format("<h1>Calibration QA report \u2014 unit {}</h1>\n", H(rec.serial));
  s += fmt::format("<p>Report id <strong class=\"report-id\" id=\"report-id\">{}</strong> \u00b7 record created {} "
                   "\u00b7 topocal {}</p>\n",
                   H(id), H(rec.created_utc), H(rec.tool_version));
  s += fmt::format("<div id=\"verdict\" class=\"banner {}\" data-verdict=\"{}\">{}<small>{} of {} checks passed "
                   "against {} ({} acceptance)</small></div>\n",
                   verdict.pass ? "pass" : "fail", verdict_word, verdict_word, verdict.checks.size() - failed,
                   verdict.checks.size(), H(limits.origin), ToString(limits.rule));
  if (!verdict.pass) {  // which checks failed, on the first page
    s += "<ul id=\"failed-checks\" class=\"failed\">\n";
    for (const std::string& f : FailedChecks(verdict)) s += fmt::format("<li>FAILED: {}</li>\n", H(f));
    s += "</ul>\n";
  }

  s += html::IdentitySection(rec, id);
  s += html::SignOffSection(inputs, verdict_word, id);
  s += html::MethodSection(rec, limits);
  s += html::CalibrationSection(rec);
  s += html::ResidualsSection(rec, limits);
  s += html::SphereSection(rec);
  s += html::PaperSection(rec);
  if (rec.device) s += html::DeviceSection(rec);
  if (inputs.previous) s += html::PreviousComparison(rec, *inputs.previous, inputs);
  s += html::AcceptanceSection(rec, limits, verdict, verdict_word, id);
  s += html::ProvenanceSection(rec, inputs);

  s += "</main>\n</td></tr></tbody></table>\n";
  s += fmt::format("<script>{}</script>\n", kImageCheckScript);
  s += "</body>\n</html>\n";
  return s;
}

namespace {

using nlohmann::json;

json ChecksJson(const Verdict& verdict) {
  json checks = json::array();
  for (const Check& c : verdict.checks) {
    json budget = json::array();
    for (const BudgetTerm& t : c.budget) budget.push_back({{"input", t.name}, {"source", t.source}, {"u", t.u}});
    json j = {{"id", c.id},
              {"what", c.what},
              {"unit", c.unit},
              {"value", c.error ? json(*c.error) : json(nullptr)},
              {"U", c.U ? json(*c.U) : json(nullptr)},
              {"coverage_factor", 2},
              {"budget", budget},
              {"limit", c.limit},
              {"verdict", c.pass ? "PASS" : "FAIL"},
              {"note", c.note}};
    if (!c.budget.empty()) j["combined_standard_uncertainty"] = CombinedStandardUncertainty(c.budget);
    checks.push_back(j);
  }
  return checks;
}

// The paper cornea: not part of the verdict.
json InformativeJson(const UnitRecord& rec, const Limits& l) {
  json informative = json::array();
  for (const Check& c : PaperCorneaRows(rec, l)) {
    informative.push_back({{"id", c.id},
                           {"what", c.what},
                           {"unit", c.unit},
                           {"value", c.error ? json(*c.error) : json(nullptr)},
                           {"U", c.U ? json(*c.U) : json(nullptr)},
                           {"coverage_factor", 2},
                           {"threshold", c.limit},
                           {"within", c.pass}});
  }
  return informative;
}

json LimitsJson(const Limits& l) {
  json limits = json::object();
  for (const NamedLimit& named : NamedLimits(l)) {
    limits[named.name] = {{"max", named.limit->max}, {"source", named.limit->source}};
  }
  return limits;
}

// The previous record of the unit: its verdict and the change of each compared quantity.
json PreviousJson(const UnitRecord& rec, const ReportInputs& inputs) {
  const Limits& l = inputs.limits;
  const Verdict vp = Evaluate(*inputs.previous, l, inputs.budget);
  json comparison = json::array();
  for (const ComparisonRow& r : ComparisonRows(rec, *inputs.previous, inputs)) {
    const auto number = [](const std::optional<double>& v) { return v ? json(*v) : json(nullptr); };
    const auto change = r.Change();
    const auto U = r.ChangeU();
    comparison.push_back({{"id", r.id},
                          {"unit", r.plain_unit},
                          {"previous", number(r.prev)},
                          {"now", number(r.now)},
                          {"change", number(change)},
                          {"U_change", number(U)},
                          {"coverage_factor", 2},
                          {"within_U", change && U ? json(std::abs(*change) <= *U) : json(nullptr)}});
  }
  return {{"record", inputs.previous->directory},
          {"unit_json_sha256", inputs.previous->unit_json_sha256},
          {"record_created_utc", inputs.previous->created_utc},
          {"verdict", vp.pass ? "PASS" : "FAIL"},
          {"comparison", comparison}};
}

}  // namespace

nlohmann::json ReportJson(const UnitRecord& rec, const ReportInputs& inputs) {
  using nlohmann::json;
  inputs.Validate(rec);
  const Limits& l = inputs.limits;
  const Verdict verdict = Evaluate(rec, l, inputs.budget);
  const json checks = ChecksJson(verdict);
  const json informative = InformativeJson(rec, l);
  const json limits = LimitsJson(l);
  const SignOff& so = inputs.sign_off;
  json out = {{"format", kReportJsonFormat},
              {"format_version", kReportJsonFormatVersion},
              {"tool_version", kVersion},
              {"report_id", ReportId(rec, inputs)},
              {"serial", rec.serial},
              {"record", rec.directory},
              {"unit_json_sha256", rec.unit_json_sha256},
              {"record_created_utc", rec.created_utc},
              {"decision_rule", ToString(l.rule)},
              {"decision_rule_text", DecisionRuleText(l.rule)},
              {"limits_origin", l.origin},
              {"limits", limits},
              {"ball_radius_U_mm", inputs.budget.ball_radius_U_mm.value_or(kDefaultBallRadiusUMm)},
              {"ball_radius_U_is_default", !inputs.budget.ball_radius_U_mm.has_value()},
              {"sign_off",
               {{"operator", so.operator_name},
                {"station", so.station},
                {"ball_certificate_id", so.ball_certificate_id},
                {"target_certificate_id", so.target_certificate_id}}},
              {"checks", checks},
              {"informative", informative},
              {"checks_passed", std::count_if(verdict.checks.begin(), verdict.checks.end(),
                                              [](const Check& c) { return c.pass; })},
              {"verdict", verdict.pass ? "PASS" : "FAIL"}};
  if (inputs.previous) out["previous"] = PreviousJson(rec, inputs);
  return out;
}

}  // namespace topocal::report

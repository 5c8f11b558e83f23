#pragma once
// Strict reading of one JSON object of a configuration file, shared by every configuration topocal reads
// (model/config.cc, harness/harness_config.cc): every key must be read or known, types and ranges are checked, and
// every failure is one ConfigError "ORIGIN: KEY: problem" naming the file and the dotted key.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "util/io.h"

namespace topocal::util {

// A JSON value as quoted in an error message, cut to ~100 characters: a bad value may be megabytes long.
inline std::string QuoteJsonValue(const nlohmann::json& v) {
  std::string s = v.dump();
  if (s.size() > 100) s = s.substr(0, 97) + "...";
  return s;
}

// Whether `s` is valid UTF-8 as the JSON writer judges it (nlohmann's dump() refuses ill-formed UTF-8 with
// type_error 316): text that passes can always be written to a JSON file.
inline bool IsValidUtf8(const std::string& s) {
  try {
    (void)nlohmann::json(s).dump();
    return true;
  } catch (const nlohmann::json::type_error&) {
    return false;
  }
}

// Whether an integer JSON value lies in [lo, hi], without the truncation of get<int>() (an unsigned value above
// LLONG_MAX is out of every int range).
inline bool JsonIntegerWithin(const nlohmann::json& v, long long lo, long long hi) {
  if (v.is_number_unsigned()) {
    const unsigned long long u = v.get<unsigned long long>();
    return hi >= 0 && u <= static_cast<unsigned long long>(hi) && static_cast<long long>(u) >= lo;
  }
  if (!v.is_number_integer()) return false;
  const long long i = v.get<long long>();
  return i >= lo && i <= hi;
}

// The one entry point for JSON text a reader takes from a file: refuses input that could crash or fool the parser
// before parsing it — more than kMaxJsonBytes, nesting deeper than kMaxJsonDepth (nlohmann's parser and dump()
// recurse: deeply nested input overflowed the stack) — and, while parsing, a key given twice in one object (which
// nlohmann would silently resolve to the last) and a number beyond double's range. Every failure is one
// ConfigError "ORIGIN: problem" (exit 2).
inline constexpr size_t kMaxJsonBytes = 64u << 20;
inline constexpr int kMaxJsonDepth = 64;
nlohmann::json ParseJsonStrict(const std::string& text, const std::string& origin);

// Throws std::runtime_error "KEY: not a finite number" for the first NaN or infinity in `j` (dotted key path,
// "[i]" for array elements): nlohmann writes both as null, which a reader would take for a missing value. Every
// JSON file topocal writes goes through it (JsonFileText).
void RequireFiniteNumbers(const nlohmann::json& j);
// The text of a JSON file topocal writes: RequireFiniteNumbers, then indented by 2 with a final newline.
std::string JsonFileText(const nlohmann::json& j);

class JsonSection {
 public:
  using json = nlohmann::json;

  JsonSection(const json& j, std::string origin, std::string prefix)
      : j_(j), origin_(std::move(origin)), prefix_(std::move(prefix)) {
    if (!j_.is_object()) Fail(prefix_.empty() ? "(top level)" : prefix_, "must be a JSON object");
  }

  [[noreturn]] void Fail(const std::string& key, const std::string& problem) const {
    throw ConfigError(fmt::format("{}: {}: {}", origin_, key, problem));
  }
  std::string Key(const std::string& k) const { return prefix_.empty() ? k : prefix_ + "." + k; }
  bool Has(const std::string& k) const { return j_.contains(k); }
  const std::string& origin() const { return origin_; }

  const json& Get(const std::string& k) {
    seen_.insert(k);
    if (!j_.contains(k)) Fail(Key(k), "missing");
    return j_.at(k);
  }

  double Number(const std::string& k) {
    const json& v = Get(k);
    if (!v.is_number()) Fail(Key(k), fmt::format("must be a number (got {})", QuoteJsonValue(v)));
    const double d = v.get<double>();
    if (!std::isfinite(d)) Fail(Key(k), "must be finite");
    return d;
  }
  double Number(const std::string& k, double fallback) { return Has(k) ? Number(k) : fallback; }
  double PositiveNumber(const std::string& k, double fallback) {
    const double v = Number(k, fallback);
    Positive(k, v);
    return v;
  }

  // An integer that fits an int: nlohmann's get<int>() truncates silently (4294967297 became 1), so the range is
  // checked on the 64-bit value first.
  int Integer(const std::string& k) {
    return IntegerInRange(k, std::numeric_limits<int>::min(), std::numeric_limits<int>::max());
  }
  int Integer(const std::string& k, int fallback) { return Has(k) ? Integer(k) : fallback; }
  // An integer within [lo, hi] (fallback when absent).
  int IntegerInRange(const std::string& k, int lo, int hi) {
    const json& v = Get(k);
    if (!v.is_number_integer()) Fail(Key(k), fmt::format("must be an integer (got {})", QuoteJsonValue(v)));
    if (!JsonIntegerWithin(v, lo, hi))
      Fail(Key(k), fmt::format("must be in [{}, {}] (got {})", lo, hi, QuoteJsonValue(v)));
    return static_cast<int>(v.get<long long>());
  }
  int IntegerInRange(const std::string& k, int fallback, int lo, int hi) {
    return Has(k) ? IntegerInRange(k, lo, hi) : fallback;
  }

  std::string String(const std::string& k) {
    const json& v = Get(k);
    if (!v.is_string()) Fail(Key(k), fmt::format("must be a string (got {})", QuoteJsonValue(v)));
    return v.get<std::string>();
  }
  std::string String(const std::string& k, const std::string& fallback) { return Has(k) ? String(k) : fallback; }

  std::string NonEmptyString(const std::string& k) {
    std::string s = String(k);
    if (s.empty()) Fail(Key(k), "must not be empty");
    return s;
  }
  bool Bool(const std::string& k) {
    const json& v = Get(k);
    if (!v.is_boolean()) Fail(Key(k), fmt::format("must be true or false (got {})", QuoteJsonValue(v)));
    return v.get<bool>();
  }
  int NonNegativeInteger(const std::string& k) { return IntegerInRange(k, 0, std::numeric_limits<int>::max()); }
  // A finite number >= 0 (an RMS, a standard deviation, an expanded uncertainty).
  double NonNegativeNumber(const std::string& k) {
    const double v = Number(k);
    if (!(v >= 0)) Fail(Key(k), fmt::format("must not be negative (got {})", v));
    return v;
  }
  // A JSON array, whose elements are read with Element() or directly.
  const json& Array(const std::string& k) {
    const json& v = Get(k);
    if (!v.is_array()) Fail(Key(k), fmt::format("must be an array (got {})", QuoteJsonValue(v)));
    return v;
  }
  // Element i of array k as an object section "k[i]".
  JsonSection Element(const std::string& k, size_t i) {
    return JsonSection(Array(k).at(i), origin_, fmt::format("{}[{}]", Key(k), i));
  }
  // Whether k is absent or null (an optional block written as null).
  bool AbsentOrNull(const std::string& k) const { return !j_.contains(k) || j_.at(k).is_null(); }
  const json& raw() const { return j_; }

  // A number within [lo, hi] (fallback when absent).
  double InRange(const std::string& k, double fallback, double lo, double hi) {
    const double v = Number(k, fallback);
    if (!(v >= lo && v <= hi)) Fail(Key(k), fmt::format("must be in [{}, {}] (got {})", lo, hi, v));
    return v;
  }
  // An array of exactly n finite numbers.
  std::vector<double> Numbers(const std::string& k, size_t n) {
    const json& v = Get(k);
    const auto bad = [&] {
      Fail(Key(k), fmt::format("must be an array of {} finite numbers (got {})", n, QuoteJsonValue(v)));
    };
    if (!v.is_array() || v.size() != n) bad();
    std::vector<double> out;
    for (const auto& e : v) {
      if (!e.is_number() || !std::isfinite(e.get<double>())) bad();
      out.push_back(e.get<double>());
    }
    return out;
  }

  void Positive(const std::string& k, double v) const {
    if (!(v > 0)) Fail(Key(k), fmt::format("must be > 0 (got {})", v));
  }
  void AtLeast(const std::string& k, int v, int lo) const {
    if (v < lo) Fail(Key(k), fmt::format("must be >= {} (got {})", lo, v));
  }

  JsonSection Child(const std::string& k) { return JsonSection(Get(k), origin_, Key(k)); }

  // Any key present but never read is an error: a misspelt key must not silently fall back to a default.
  void RejectUnknown() const {
    for (auto it = j_.begin(); it != j_.end(); ++it) {
      if (!seen_.count(it.key())) Fail(Key(it.key()), "unknown key");
    }
  }
  void MarkSeen(const std::string& k) { seen_.insert(k); }

 private:
  const json& j_;
  std::string origin_;
  std::string prefix_;
  std::set<std::string> seen_;
};

}  // namespace topocal::util

#include "util/json_section.h"
#include "util/json_strict.h"

#include <stdexcept>
#include <vector>

namespace topocal::util {
namespace {

// "a.b[].c", each key cut to 40 characters: keys come from the input and may be long.
std::string DottedPath(const std::vector<std::string>& path) {
  std::string out;
  for (const std::string& p : path) {
    if (p.empty()) continue;
    if (p == "[]") {
      out += p;
      continue;
    }
    if (!out.empty()) out += '.';
    out += p.size() > 40 ? p.substr(0, 37) + "..." : p;
  }
  return out;
}

}  // namespace

nlohmann::json ParseJsonStrict(const std::string& text, const std::string& origin) {
  if (text.size() > kMaxJsonBytes) {
    throw ConfigError(fmt::format("{}: {} bytes: larger than the {} MiB a configuration may have", origin, text.size(),
                                  kMaxJsonBytes >> 20));
  }
  return ParseJsonStrictUpTo(text, origin, kMaxJsonBytes);
}

nlohmann::json ParseJsonStrictUpTo(const std::string& text, const std::string& origin, size_t max_bytes) {
  using json = nlohmann::json;
  if (text.size() > max_bytes) {
    throw ConfigError(
        fmt::format("{}: {} bytes: larger than the {} MiB such a file may have", origin, text.size(), max_bytes >> 20));
  }
  // Nesting depth outside strings, before the (recursive) parser sees the text.
  int depth = 0;
  bool in_string = false, escaped = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
      continue;
    }
    if (c == '"')
      in_string = true;
    else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) {
        throw ConfigError(fmt::format("{}: nested deeper than {} levels (byte {})", origin, kMaxJsonDepth, i));
      }
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  // Per open object, the keys seen (a key given twice is refused); per open container, the key or "[]" it sits
  // under, so that an error of the lexer (a number beyond double's range) can name where it is.
  std::vector<std::set<std::string>> keys;
  std::vector<std::string> path;
  std::string duplicate;
  const json::parser_callback_t check = [&](int /*depth*/, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
        keys.emplace_back();
        path.emplace_back();
        break;
      case json::parse_event_t::array_start:
        path.emplace_back("[]");
        break;
      case json::parse_event_t::object_end:
        if (!keys.empty()) keys.pop_back();
        [[fallthrough]];
      case json::parse_event_t::array_end:
        if (!path.empty()) path.pop_back();
        break;
      case json::parse_event_t::key: {
        const std::string& k = parsed.get_ref<const std::string&>();
        if (!path.empty()) path.back() = k;
        if (!keys.empty() && !keys.back().insert(k).second && duplicate.empty()) duplicate = DottedPath(path);
        break;
      }
      case json::parse_event_t::value:
        break;
    }
    return true;
  };
  json j;
  try {
    j = json::parse(text, check);
  } catch (const json::parse_error& e) {
    throw ConfigError(fmt::format("{}: not valid JSON (byte {})", origin, e.byte));
  } catch (const json::out_of_range& e) {  // 406: a number like 1e999; its text is not echoed (it may be huge)
    const std::string where = DottedPath(path);
    throw ConfigError(
        fmt::format("{}: {}: a number beyond the range of a double", origin, where.empty() ? "(top level)" : where));
  } catch (const json::exception& e) {
    throw ConfigError(fmt::format("{}: not valid JSON (nlohmann error {})", origin, e.id));
  }
  if (!duplicate.empty()) throw ConfigError(fmt::format("{}: {}: given twice in one object", origin, duplicate));
  return j;
}

namespace {
void CheckFinite(const nlohmann::json& j, const std::string& where) {
  if (j.is_object()) {
    for (const auto& [k, v] : j.items()) CheckFinite(v, where.empty() ? k : where + "." + k);
  } else if (j.is_array()) {
    for (size_t i = 0; i < j.size(); ++i) CheckFinite(j[i], fmt::format("{}[{}]", where, i));
  } else if (j.is_number_float() && !std::isfinite(j.get<double>())) {
    throw std::runtime_error(fmt::format("{}: not a finite number", where));
  }
}
}  // namespace

void RequireFiniteNumbers(const nlohmann::json& j) { CheckFinite(j, ""); }

std::string JsonFileText(const nlohmann::json& j) {
  RequireFiniteNumbers(j);
  return j.dump(2) + "\n";
}

}  // namespace topocal::util

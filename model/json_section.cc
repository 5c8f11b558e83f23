#include "model/json_section.h"

#include <vector>

namespace topocal::model {

nlohmann::json ParseJsonStrict(const std::string& text, const std::string& origin) {
  using json = nlohmann::json;
  if (text.size() > kMaxJsonBytes) {
    throw ConfigError(fmt::format("{}: {} bytes: larger than the {} MiB a configuration may have", origin, text.size(),
                                  kMaxJsonBytes >> 20));
  }
  // Nesting depth outside strings, before the (recursive) parser sees the text.
  int depth = 0;
  bool in_string = false, escaped = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
      continue;
    }
    if (c == '"') in_string = true;
    else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) {
        throw ConfigError(fmt::format("{}: nested deeper than {} levels (byte {})", origin, kMaxJsonDepth, i));
      }
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  std::vector<std::set<std::string>> keys;  // per open object
  std::string duplicate;
  const json::parser_callback_t check = [&](int /*depth*/, json::parse_event_t event, json& parsed) {
    if (event == json::parse_event_t::object_start) keys.emplace_back();
    if (event == json::parse_event_t::object_end && !keys.empty()) keys.pop_back();
    if (event == json::parse_event_t::key && !keys.empty() && !keys.back().insert(parsed.get<std::string>()).second &&
        duplicate.empty()) {
      duplicate = parsed.get<std::string>();
    }
    return true;
  };
  json j;
  try {
    j = json::parse(text, check);
  } catch (const json::parse_error& e) {
    throw ConfigError(fmt::format("{}: not valid JSON (byte {})", origin, e.byte));
  } catch (const json::exception& e) {  // out_of_range for a number like 1e999
    throw ConfigError(fmt::format("{}: not valid JSON: a number out of range or malformed ({})", origin, e.id));
  }
  if (!duplicate.empty()) {
    throw ConfigError(fmt::format("{}: {}: given twice in one object", origin, duplicate.substr(0, 100)));
  }
  return j;
}

}  // namespace topocal::model

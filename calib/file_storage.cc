#include "calib/file_storage.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <limits>
#include <string_view>
#include <vector>

#include "util/io.h"

namespace topocal::calib {

// Written by hand: no library offers a non-recursive pre-scan of OpenCV's three formats. The count is deliberately
// crude — an upper bound, not a parser.
int FileStorageNestingBound(const std::string& text) {
  int depth = 0, deepest = 0, openers = 0;
  char quote = 0;          // the open quote character, 0 outside strings
  bool line_start = true;  // only blanks and "- " seen on this line so far
  int dashes = 0;          // "- " block-sequence entries opened on this line
  char previous = '\n';
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quote) {
      if (c == '\\' && quote == '"') {
        ++i;  // skip the escaped character
      } else if (c == quote) {
        quote = 0;
      }
      previous = c;
      continue;
    }
    if (c == '\n') {
      line_start = true;
      dashes = 0;
      previous = c;
      continue;
    }
    if (line_start && c == '-' && i + 1 < text.size() && (text[i + 1] == ' ' || text[i + 1] == '\t')) {
      ++dashes;
      deepest = std::max(deepest, depth + dashes);
      previous = c;
      continue;
    }
    if (c != ' ' && c != '\t') line_start = false;
    // A quote opens a string only where a scalar can start: "it's" in a plain scalar is no string.
    const bool token_start = previous == ' ' || previous == '\t' || previous == '\n' || previous == '[' ||
                             previous == '{' || previous == ',' || previous == ':' || previous == '>';
    if ((c == '"' || c == '\'') && token_start) {
      quote = c;
    } else if (c == '[' || c == '{') {
      ++depth;
      ++openers;
    } else if (c == ']' || c == '}') {
      depth = std::max(0, depth - 1);
    } else if (c == '<') {  // XML: <tag> opens, </tag> and <tag/> do not nest; <?...?> and <!...> neither
      const char next = i + 1 < text.size() ? text[i + 1] : '\0';
      const size_t close = text.find('>', i);
      const bool self_closing = close != std::string::npos && close > i && text[close - 1] == '/';
      if (next == '/') {
        depth = std::max(0, depth - 1);
      } else if (next != '?' && next != '!' && !self_closing) {
        ++depth;
        ++openers;
      }
    }
    deepest = std::max(deepest, depth);
    previous = c;
  }
  // Closers inside strings the scan did not recognise as strings could hide nesting; the total count of openers
  // bounds the depth whatever the quoting (OpenCV 4.6 survives 20000 levels; 1e5 overflowed its stack).
  constexpr int kMaxOpeners = 10000;
  return openers > kMaxOpeners ? std::max(deepest, kMaxFileStorageDepth + 1) : deepest;
}

std::string FileStorageIntegerOutOfRange(const std::string& text) {
  const auto delimiter = [](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == ',' || c == '[' || c == ']' || c == '{' ||
           c == '}' || c == ':' || c == '<' || c == '>' || c == '"' || c == '\'';
  };
  char quote = 0;
  int line = 1;
  size_t i = 0;
  while (i < text.size()) {
    const char c = text[i];
    if (c == '\n') ++line;
    if (quote) {
      if (c == '\\' && quote == '"') ++i;
      else if (c == quote) quote = 0;
      ++i;
      continue;
    }
    if ((c == '"' || c == '\'') && (i == 0 || delimiter(text[i - 1]))) {
      quote = c;
      ++i;
      continue;
    }
    if (delimiter(c)) {
      ++i;
      continue;
    }
    size_t end = i;
    while (end < text.size() && !delimiter(text[end])) ++end;
    const std::string token = text.substr(i, end - i);
    size_t p = token[0] == '+' || token[0] == '-' ? 1 : 0;
    const bool hex = token.size() > p + 2 && token[p] == '0' && (token[p + 1] == 'x' || token[p + 1] == 'X');
    bool integer = token.size() > p;
    for (size_t k = hex ? p + 2 : p; k < token.size() && integer; ++k) {
      integer = hex ? std::isxdigit(static_cast<unsigned char>(token[k])) != 0
                    : std::isdigit(static_cast<unsigned char>(token[k])) != 0;
    }
    if (integer) {
      errno = 0;
      const long long v = std::strtoll(token.c_str(), nullptr, 0);
      if (errno == ERANGE || v > std::numeric_limits<int>::max() || v < std::numeric_limits<int>::min()) {
        return fmt::format("line {}: {}", line, token.size() > 40 ? token.substr(0, 37) + "..." : token);
      }
    }
    i = end;
  }
  return "";
}

std::string FileStorageUnquotedNonAscii(const std::string& text) {
  char quote = 0;
  bool comment = false;
  int line = 1;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '\n') {
      ++line;
      comment = false;
      quote = 0;  // OpenCV's YAML strings do not span lines
      continue;
    }
    if (comment) continue;
    if (quote) {
      if (c == '\\' && quote == '"') ++i;
      else if (c == quote) quote = 0;
      continue;
    }
    if (c == '"' || c == '\'') {
      quote = c;
    } else if (c == '#' && (i == 0 || text[i - 1] == ' ' || text[i - 1] == '\t' || text[i - 1] == '\n')) {
      comment = true;
    } else if (static_cast<unsigned char>(c) >= 0x80) {
      return fmt::format("line {}", line);
    }
  }
  return "";
}

std::string FileStorageYamlLineProblem(const std::string& text) {
  int flow = 0;     // open '[' / '{' outside quotes, across lines
  char quote = 0;   // within a quoted scalar (OpenCV's do not span lines, but a flow value may)
  int line_no = 0;
  size_t root_indent = std::string::npos;  // indentation of the document's first line of content
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + start, end - start);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    ++line_no;
    start = end + 1;
    size_t i = 0;
    if (flow == 0 && quote == 0) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
      const std::string_view content = line.substr(i);
      if (content.substr(0, 3) == "---" || content.substr(0, 3) == "...") {
        root_indent = std::string::npos;  // a new document
        continue;
      }
      if (content.empty() || content[0] == '#' || content[0] == '%') continue;
      // Nothing may stand left of the document's root: " s: 5" then "x: 1" is not YAML (and OpenCV's parser loops
      // on some such dedents).
      if (root_indent == std::string::npos) root_indent = i;
      if (i < root_indent) return fmt::format("line {}", line_no);
      bool item = false;  // "- " list items, possibly nested on one line ("- - x")
      while (i < line.size() && line[i] == '-' && (i + 1 == line.size() || line[i + 1] == ' ')) {
        item = true;
        ++i;
        while (i < line.size() && line[i] == ' ') ++i;
      }
      const std::string_view rest = line.substr(i);
      const bool value_start = rest.empty() || rest[0] == '[' || rest[0] == '{' || rest[0] == '"' || rest[0] == '\'';
      if (!item && !value_start) {
        // A block mapping's line: KEY ":" then a space, a comment or the end of the line.
        size_t colon = rest.find(':');
        while (colon != std::string_view::npos && colon + 1 < rest.size() && rest[colon + 1] != ' ' &&
               rest[colon + 1] != '\t') {
          colon = rest.find(':', colon + 1);
        }
        if (colon == std::string_view::npos || colon == 0 || rest.substr(0, colon).find(" -") != std::string_view::npos) {
          return fmt::format("line {}", line_no);
        }
      }
    }
    for (; i < line.size(); ++i) {
      const char c = line[i];
      if (quote) {
        if (c == '\\' && quote == '"') ++i;
        else if (c == quote) quote = 0;
      } else if (c == '"' || c == '\'') {
        quote = c;
      } else if (c == '#' && (i == 0 || line[i - 1] == ' ')) {
        break;
      } else if (c == '[' || c == '{') {
        ++flow;
      } else if ((c == ']' || c == '}') && flow > 0) {
        --flow;
      }
    }
    if (flow == 0) quote = 0;
  }
  return "";
}

namespace {

// The first key that a mapping holds twice, as a dotted path ("" if none). OpenCV keeps both entries and reads the
// first, so a second value written further down a file would be silently ignored.
std::string FirstDuplicateKey(const cv::FileNode& node, const std::string& path) {
  if (node.isMap()) {
    std::vector<std::string> keys = node.keys();
    std::vector<std::string> sorted = keys;
    std::sort(sorted.begin(), sorted.end());
    if (const auto dup = std::adjacent_find(sorted.begin(), sorted.end()); dup != sorted.end()) {
      return path.empty() ? *dup : path + "." + *dup;
    }
    for (const std::string& k : keys) {
      if (std::string d = FirstDuplicateKey(node[k], path.empty() ? k : path + "." + k); !d.empty()) return d;
    }
  } else if (node.isSeq()) {
    for (size_t i = 0; i < node.size(); ++i) {
      if (std::string d = FirstDuplicateKey(node[static_cast<int>(i)], fmt::format("{}[{}]", path, i)); !d.empty()) {
        return d;
      }
    }
  }
  return "";
}

}  // namespace

cv::FileStorage OpenFileStorage(const std::string& text, const std::string& origin) {
  if (text.size() > kMaxFileStorageBytes) {
    throw util::InputError(fmt::format("{}: {} bytes: larger than the {} MiB a calibration or target file may have",
                                       origin, text.size(), kMaxFileStorageBytes >> 20));
  }
  if (text.find('\0') != std::string::npos)
    throw util::InputError(fmt::format("{}: a NUL byte: not a text file", origin));
  if (FileStorageNestingBound(text) > kMaxFileStorageDepth) {
    throw util::InputError(fmt::format("{}: nested deeper than {} levels", origin, kMaxFileStorageDepth));
  }
  if (const std::string bad = FileStorageIntegerOutOfRange(text); !bad.empty()) {
    throw util::InputError(fmt::format("{}: {}: an integer beyond the range of int", origin, bad));
  }
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) throw util::InputError(fmt::format("{}: empty file", origin));
  // cv::FileStorage reads YAML from memory only after a "%YAML" directive; Kalibr's files have none.
  std::string body = text;
  int format = cv::FileStorage::FORMAT_AUTO;
  if (text[first] == '<') {
    format = cv::FileStorage::FORMAT_XML;
  } else if (text[first] == '{') {
    format = cv::FileStorage::FORMAT_JSON;
  } else {
    format = cv::FileStorage::FORMAT_YAML;
    if (const std::string at = FileStorageUnquotedNonAscii(text); !at.empty()) {
      throw util::InputError(
          fmt::format("{}: {}: a non-ASCII byte outside a quoted string or comment (keys and "
                      "plain values are ASCII; quote the value)",
                      origin, at));
    }
    if (const std::string at = FileStorageYamlLineProblem(text); !at.empty()) {
      throw util::InputError(
          fmt::format("{}: {}: not a line of a YAML mapping (\"name: value\", \"- value\", "
                      "indented no less than the first key)",
                      origin, at));
    }
    if (text.compare(first, 5, "%YAML") != 0) body = "%YAML:1.0\n---\n" + text;
  }
  cv::FileStorage fs;
  const char* format_name = format == cv::FileStorage::FORMAT_XML    ? "XML"
                            : format == cv::FileStorage::FORMAT_JSON ? "JSON"
                                                                     : "YAML";
  // OpenCV's parsers throw cv::Exception, and std::length_error from inside on some malformed keys (the fuzzer's
  // ":t: d" in a matrix aborted the process): both are bad input.
  ReadFileStorage(origin, fmt::format("valid {}", format_name).c_str(), [&] {
    fs.open(body, cv::FileStorage::READ | cv::FileStorage::MEMORY | format);
  });
  if (!fs.isOpened()) throw util::InputError(fmt::format("{}: cannot be read as YAML, XML or JSON", origin));
  if (const std::string key = FirstDuplicateKey(fs.root(), ""); !key.empty()) {
    throw util::InputError(fmt::format("{}: {}: the key appears twice (which one is meant?)", origin, key));
  }
  return fs;
}

}  // namespace topocal::calib

#pragma once
// What the command line passes to the libraries' Run functions for their side channels: progress drawn as
// tools/progress.h's line on stderr, and diagnostic lines on stderr behind the verb's prefix.
#include <fmt/format.h>

#include <memory>
#include <string>
#include <utility>

#include "tools/progress.h"
#include "util/progress_display.h"

namespace topocal::tools {

// Each task shown as "<prefix><what>" (prefix e.g. "topocal harness: ").
inline util::ShowProgress ProgressOnStderr(std::string prefix) {
  struct Line final : util::ProgressDisplay {
    explicit Line(std::string what) : progress(std::move(what)) {}
    void Update(std::size_t done, std::size_t total) override { progress.Update(done, total); }
    Progress progress;
  };
  return [prefix = std::move(prefix)](const std::string& what) { return std::make_unique<Line>(prefix + what); };
}

// Each line as "<prefix><line>\n" on stderr (prefix e.g. "topocal calibrate: ").
inline util::LogLine LogOnStderr(std::string prefix) {
  return [prefix = std::move(prefix)](const std::string& line) { fmt::print(stderr, "{}{}\n", prefix, line); };
}

}  // namespace topocal::tools

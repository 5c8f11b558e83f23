#pragma once
// How library code that runs for seconds lets its caller show that it is working, without knowing where it is
// shown: the command line redraws one line on stderr (util/terminal_progress.h); a test or a binding may show nothing.
// Also the one type for the diagnostic lines a run reports beside its result (skipped inputs, warnings).
#include <cstddef>
#include <functional>
#include <memory>
#include <string>

namespace topocal::util {

// Shows one task while it exists (its `what` from the start, done/total as they come) and stops when destroyed.
class ProgressDisplay {
 public:
  virtual ~ProgressDisplay() = default;
  virtual void Update(std::size_t done, std::size_t total) = 0;
};

// Starts showing `what`; may return nullptr (nothing shown).
using ShowProgress = std::function<std::unique_ptr<ProgressDisplay>(const std::string& what)>;

// One diagnostic line, without its newline.
using LogLine = std::function<void(const std::string& line)>;

// The display of `what`, or nullptr when the caller asked for none.
inline std::unique_ptr<ProgressDisplay> StartProgress(const ShowProgress& show, const std::string& what) {
  return show ? show(what) : nullptr;
}

// Reports `line` when the caller asked for diagnostics.
inline void Log(const LogLine& log, const std::string& line) {
  if (log) log(line);
}

}  // namespace topocal::util

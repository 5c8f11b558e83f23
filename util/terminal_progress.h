#pragma once
// util/progress_display.h shown on a terminal: progress on stderr for what can take more than ~2 s (render-target,
// harness, unit calibrate, --uncertainty), as the command line shows it. One line, redrawn in place 4 times a second, first drawn after 1 s (quick runs print nothing) and erased at the
// end, so stdout and the final messages stay clean. Silent when stderr is not a terminal (logs, CI, pipes) or with
// the global --quiet.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <string>
#include <thread>

#include "util/progress_display.h"

namespace topocal::util {

void SetQuiet(bool quiet);
// Whether progress lines are drawn: stderr is a terminal and --quiet was not given.
bool ProgressEnabled();

class Progress final : public ProgressDisplay {
 public:
  // `what`: e.g. "topocal harness: cases" or "topocal render-target: rendering 4000 x 3000".
  explicit Progress(std::string what);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  // Thread-safe; without a call the line shows the elapsed time only.
  void Update(std::size_t done, std::size_t total) override;
  // Prints a whole line on stderr (a step the verb reports), over the progress line, which is redrawn below it.
  void Line(const std::string& text);

 private:
  void Loop();
  std::string what_;
  std::atomic<std::size_t> done_{0}, total_{0};
  std::chrono::steady_clock::time_point start_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  bool drawn_ = false;
  std::thread thread_;
};

// Each task shown as a Progress line "<prefix><what>" (prefix e.g. "topocal harness: ").
ShowProgress ProgressOnStderr(std::string prefix);
// Each line as "<prefix><line>\n" on stderr (prefix e.g. "topocal calibrate: ").
LogLine LogOnStderr(std::string prefix);

}  // namespace topocal::util

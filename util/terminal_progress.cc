#include "util/terminal_progress.h"

#include <unistd.h>

#include <cstdio>
#include <memory>
#include <utility>

#include <fmt/format.h>

namespace topocal::util {
namespace {

std::atomic<bool> g_quiet{false};
constexpr auto kFirstDraw = std::chrono::seconds(1);
constexpr auto kRedraw = std::chrono::milliseconds(250);

}  // namespace

void SetQuiet(bool quiet) { g_quiet = quiet; }

bool ProgressEnabled() { return !g_quiet && ::isatty(STDERR_FILENO) != 0; }

Progress::Progress(std::string what) : what_(std::move(what)), start_(std::chrono::steady_clock::now()) {
  if (ProgressEnabled()) thread_ = std::thread([this] { Loop(); });
}

Progress::~Progress() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
  if (drawn_) {
    fmt::print(stderr, "\r\033[K");  // erase the line: what follows is the verb's own output
    std::fflush(stderr);
  }
}

void Progress::Update(std::size_t done, std::size_t total) {
  total_ = total;
  done_ = done;
}

void Progress::Line(const std::string& text) {
  std::lock_guard lock(mutex_);
  fmt::print(stderr, "{}{}\n", drawn_ ? "\r\033[K" : "", text);
  std::fflush(stderr);
}

void Progress::Loop() {
  std::unique_lock lock(mutex_);
  if (wake_.wait_for(lock, kFirstDraw, [this] { return stop_; })) return;
  do {
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const std::size_t total = total_, done = done_;
    if (total > 0) {
      fmt::print(stderr, "\r\033[K{}: {}/{} ({:.0f} %), {:.0f} s", what_, done, total, 100.0 * done / total, seconds);
    } else {
      fmt::print(stderr, "\r\033[K{} ... {:.0f} s", what_, seconds);
    }
    std::fflush(stderr);
    drawn_ = true;
  } while (!wake_.wait_for(lock, kRedraw, [this] { return stop_; }));
}

ShowProgress ProgressOnStderr(std::string prefix) {
  return [prefix = std::move(prefix)](const std::string& what) { return std::make_unique<Progress>(prefix + what); };
}

LogLine LogOnStderr(std::string prefix) {
  return [prefix = std::move(prefix)](const std::string& line) { fmt::print(stderr, "{}{}\n", prefix, line); };
}

}  // namespace topocal::util

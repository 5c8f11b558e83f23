#pragma once
// No empty folder left by a failing verb. Constructed before a verb writes into DIR, it remembers which of DIR and
// its ancestors do not exist yet; if the verb then leaves by an exception, it removes those of them that are empty,
// deepest first. Only empty ones: a directory that now holds anything (another process's unit record in a shared
// units/, a report written before a FAIL verdict) is never touched, so concurrent runs are safe.
#include <exception>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

namespace topocal::util {

class NewDirectoryGuard {
 public:
  explicit NewDirectoryGuard(const std::string& dir) : exceptions_(std::uncaught_exceptions()) {
    std::error_code ec;
    std::filesystem::path p = std::filesystem::absolute(dir, ec).lexically_normal();
    if (ec) return;
    if (p.filename().empty()) p = p.parent_path();  // "units/SN/" is "units/SN"
    while (!p.empty() && !std::filesystem::exists(p, ec)) {
      missing_.push_back(p);
      if (p == p.parent_path()) break;
      p = p.parent_path();
    }
  }
  ~NewDirectoryGuard() {
    if (std::uncaught_exceptions() <= exceptions_) return;
    std::error_code ec;
    for (const auto& p : missing_) {
      if (std::filesystem::is_directory(p, ec) && std::filesystem::is_empty(p, ec)) std::filesystem::remove(p, ec);
    }
  }
  NewDirectoryGuard(const NewDirectoryGuard&) = delete;
  NewDirectoryGuard& operator=(const NewDirectoryGuard&) = delete;

 private:
  int exceptions_;
  std::vector<std::filesystem::path> missing_;  // deepest first
};

}  // namespace topocal::util

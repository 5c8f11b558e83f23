#pragma once
// File output that never leaves a partial file behind: write to a temporary file beside the target, then rename.
#include <stdexcept>
#include <string>
#include <string_view>

namespace topocal::model {

// Bad input or an output that cannot be written: the message is one line naming the file and the problem.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Writes `content` to `path` atomically (temporary file + rename). Throws InputError naming the path on failure.
void WriteFileAtomic(const std::string& path, std::string_view content);
// Reads a whole file; throws InputError naming the path if it cannot be read.
std::string ReadFile(const std::string& path);

}  // namespace topocal::model

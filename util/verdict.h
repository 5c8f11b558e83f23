#pragma once
// A check that ran to the end and said no (a QA verdict of FAIL): the output is complete and written; the command
// line prints the message and exits 3, so that a production line's script can gate on the verdict.
#include <stdexcept>

namespace topocal::util {

class VerdictFailed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace topocal::util

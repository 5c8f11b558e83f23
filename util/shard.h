#pragma once
// One slice of a run split across processes or machines (--shard i/N): the items whose index % N == i. Shared by
// the harness and unit calibrate-batch (docs/scale-out.md).
#include <string>

namespace topocal::util {

struct ShardSpec {
  int index = 0;
  int count = 1;
};
// "i/N" with 0 <= i < N; throws util::InputError ("--shard: ...") otherwise.
ShardSpec ParseShardSpec(const std::string& text);

}  // namespace topocal::util

#pragma once
// The build's provenance beyond the version (util/version.h): the source tree's git commit, written into every unit
// record and shown by `topocal --version`, so that a record names the exact code that computed it.
namespace topocal {

// The commit's short hash ("1a2b3c4d5e6f"), with "-dirty" when the tree had uncommitted changes to tracked files,
// "unknown" when built outside a git checkout (cmake/build_commit.cmake; regenerated at every build).
const char* BuildCommit() noexcept;

}  // namespace topocal

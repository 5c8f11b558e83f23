#pragma once
// Where the CLI finds its bundled data (the default design and camera of `unit`): $TOPOCAL_DATA_DIR if set, else
// <directory of the executable>/../share/topocal/data — the installed layout, which the build tree mirrors
// (cmake/install.cmake). Never a path fixed at build time: a moved or installed binary keeps working.
#include <string>

namespace topocal::tools {

// Throws util::InputError naming what was tried when no data directory is found.
std::string DataDir();

}  // namespace topocal::tools

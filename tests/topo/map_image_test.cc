#include "topo/map_image.h"

#include <gtest/gtest.h>

namespace topocal::topo {
namespace {}  // namespace
}  // namespace topocal::topo

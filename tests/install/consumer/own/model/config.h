#pragma once
// The consumer's own model/config.h, first on its include path: topocal's installed headers must never include it.
#error "a topocal header included the consumer's model/config.h"

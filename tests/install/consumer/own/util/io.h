#pragma once
// The consumer's own util/io.h, first on its include path: topocal's installed headers must never include it.
#error "a topocal header included the consumer's util/io.h"

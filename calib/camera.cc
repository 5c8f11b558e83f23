#include "calib/camera.h"
// CameraModel is header-only today; this translation unit anchors the library and checks the header compiles alone.

// topocal-detect — `topocal detect` (cmd_detect.cc), which `topocal` (launcher.cc) hands to this program: a capture's
// fixed cost is mostly loading the program's libraries, and detection needs OpenCV's core and imgproc but none of the
// calibration, drawing, database and digest libraries every other verb brings into topocal-full (docs/startup.md).
// Linked with --as-needed against the libraries detection's code uses.
#include <CLI/CLI.hpp>

#include "imageio/large_buffers.h"
#include "tools/cli_app.h"
#include "tools/commands.h"

int main(int argc, char** argv) {
  CLI::App app{topocal::tools::kAppDescription};
  topocal::tools::SetUpApp(app);
  topocal::imageio::UseHugePagesForImageBuffers();  // frames and their masks: one fault per 2 MB, not per 4 KB
  topocal::tools::AddDetectCommand(app);
  return topocal::tools::RunApp(app, argc, argv);
}

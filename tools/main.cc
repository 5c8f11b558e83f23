// topocal-full — every verb of the topocal command line. Users run `topocal` (launcher.cc), which hands `--version`
// and the sweep to topocal-sweep (sweep_main.cc, no OpenCV) and every other command line to this program unchanged.
#include <CLI/CLI.hpp>

#include "imageio/large_buffers.h"
#include "tools/cli_app.h"
#include "tools/commands.h"

int main(int argc, char** argv) {
  CLI::App app{topocal::tools::kAppDescription};
  topocal::tools::SetUpApp(app);
  topocal::imageio::UseHugePagesForImageBuffers();  // frames and their masks: one fault per 2 MB, not per 4 KB
  topocal::tools::AddDesignCommand(app);
  topocal::tools::AddSimulateCommand(app);
  topocal::tools::AddSweepCommand(app, &topocal::tools::kSweepImageStages);
  topocal::tools::AddReconstructCommand(app);
  topocal::tools::AddRenderSpotsCommand(app);
  topocal::tools::AddDetectCommand(app);
  topocal::tools::AddUndistortCommand(app);
  topocal::tools::AddCalibrateCommand(app);
  topocal::tools::AddTargetCommand(app);
  topocal::tools::AddRenderTargetCommand(app);
  topocal::tools::AddUnitCommand(app);
  topocal::tools::AddHarnessCommand(app);
  topocal::tools::AddReportCommand(app);
  topocal::tools::AddDeviceCommand(app);
  topocal::tools::AddFleetCommand(app);
  topocal::tools::AddCompareCommand(app);
  topocal::tools::AddExportCommands(app);
  topocal::tools::FinishHelp(app);
  return topocal::tools::RunApp(app, argc, argv);
}

// topocal — camera-distortion calibration and correction for cone corneal topographers.
// Exit codes: 0 success; 1 a computation failed (solver did not converge, no usable data); 2 bad input
// (usage, missing or corrupt file, invalid configuration); 3 a QA verdict of FAIL (the report is written).
#include <fmt/format.h>
#include <glog/logging.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "model/config.h"
#include "tools/commands.h"
#include "tools/progress.h"
#include "util/io.h"
#include "util/version.h"

int main(int argc, char** argv) {
  // Before any thread starts: SIGINT/SIGTERM/SIGHUP remove staged outputs, then end the process (model/io.h).
  topocal::util::InstallSignalCleanup();
  // Ceres logs through glog (failed steps, rank-deficient covariances); every failure reaches the user as one line
  // from the library's own result, so glog's lines would only be noise on stderr.
  FLAGS_minloglevel = google::GLOG_FATAL;
  CLI::App app{"topocal: calibrate, correct and verify the camera of a cone (null-screen) corneal topographer"};
  app.set_version_flag("--version", std::string("topocal ") + topocal::kVersion);
  app.require_subcommand(1);
  // Every option shows its default in --help (subcommands inherit this when they are created).
  app.option_defaults()->always_capture_default();
  // --quiet anywhere on the line (before or after the verb): no progress lines on stderr.
  bool quiet = false;
  app.add_flag("--quiet", quiet, "No progress lines on stderr (they are off anyway when stderr is not a terminal)");
  app.fallthrough();
  app.parse_complete_callback([&quiet] { topocal::tools::SetQuiet(quiet); });
  topocal::tools::AddDesignCommand(app);
  topocal::tools::AddSimulateCommand(app);
  topocal::tools::AddSweepCommand(app);
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
  topocal::tools::AddExportCommands(app);
  topocal::tools::FinishHelp(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  } catch (const topocal::util::ConfigError& e) {
    fmt::print(stderr, "topocal: {}\n", e.what());
    return 2;
  } catch (const topocal::util::InputError& e) {
    fmt::print(stderr, "topocal: {}\n", e.what());
    return 2;
  } catch (const topocal::tools::VerdictFailed& e) {
    fmt::print(stderr, "topocal: {}\n", e.what());
    return 3;
  } catch (const std::exception& e) {
    fmt::print(stderr, "topocal: {}\n", e.what());
    return 1;
  }
  return 0;
}

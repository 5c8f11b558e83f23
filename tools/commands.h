#pragma once
// Each verb of the `topocal` command line lives in its own cmd_<verb>.cc and registers itself here.
// A command's callback throws util::ConfigError / util::InputError for bad input (exit 2) and
// std::runtime_error for a computation that failed (exit 1); main() turns them into one line on stderr.
#include <CLI/CLI.hpp>

#include "report/sweep_command.h"
#include "util/io.h"
#include "util/verdict.h"

namespace topocal::tools {

using util::VerdictFailed;

void AddDesignCommand(CLI::App& app);
void AddSimulateCommand(CLI::App& app);
// The sweep's two stages that need OpenCV (report/sweep_command.h). topocal-full passes kSweepImageStages
// (cmd_sweep_stages.cc); topocal-sweep, which links no OpenCV, passes nullptr, and a sweep that asks for either throws
// NeedsFullCli (cli_app.h).
using report::SweepImageStages;
extern const SweepImageStages kSweepImageStages;
void AddSweepCommand(CLI::App& app, const SweepImageStages* image_stages);
void AddReconstructCommand(CLI::App& app);
void AddRenderSpotsCommand(CLI::App& app);
void AddUndistortCommand(CLI::App& app);
void AddCalibrateCommand(CLI::App& app);
void AddTargetCommand(CLI::App& app);
void AddRenderTargetCommand(CLI::App& app);
void AddUnitCommand(CLI::App& app);
void AddHarnessCommand(CLI::App& app);
void AddReportCommand(CLI::App& app);
void AddDeviceCommand(CLI::App& app);
void AddFleetCommand(CLI::App& app);
void AddCompareCommand(CLI::App& app);  // cmd_compare.cc
void AddDetectCommand(CLI::App& app);
void AddExportCommands(CLI::App& app);  // export and import (cmd_export.cc)

// After every verb is added: one example per verb as its --help footer, and one syntax for lists (help.cc).
void FinishHelp(CLI::App& app);

}  // namespace topocal::tools

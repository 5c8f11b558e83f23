#pragma once
// What topocal-full (main.cc) and topocal-sweep (sweep_main.cc) share: the application's description, version and global
// options, and how a command's outcome becomes an exit code.
// Exit codes: 0 success; 1 a computation failed (solver did not converge, no usable data); 2 bad input (usage,
// missing or corrupt file, invalid configuration); 3 a QA verdict of FAIL (the report is written); 4 a measurement
// refused because the capture cannot support it (util::MeasurementRefused; the reasons are printed).
#include <CLI/CLI.hpp>

namespace topocal::tools {

inline constexpr const char* kAppDescription =
    "topocal: calibrate, correct and verify the camera of a cone (null-screen) corneal topographer";

// Installs the signal cleanup (before any thread starts), silences glog (Ceres' lines; every failure reaches the
// user as one line from the library's own result) and adds --version and --quiet.
void SetUpApp(CLI::App& app);

// Parses and runs; every exception of a command becomes one line on stderr and its exit code. NeedsFullCli passes
// through (sweep_main.cc).
int RunApp(CLI::App& app, int argc, char** argv);

// Thrown, before any work or output, by a command topocal-sweep cannot run in its own process (a stage that needs
// OpenCV): topocal-sweep hands the whole command line to topocal-full. Not a std::exception, so that nothing in
// between reports it as a failure.
struct NeedsFullCli {};

}  // namespace topocal::tools

#include "tools/cli_app.h"

#include <fmt/format.h>
#include <glog/logging.h>

#include <cstdio>
#include <exception>
#include <memory>
#include <string>

#include "tools/commands.h"
#include "util/terminal_progress.h"
#include "util/allocator.h"
#include "util/build_info.h"
#include "util/io.h"
#include "util/version.h"

namespace topocal::tools {

namespace {

// An option given an empty value (`--sigma ''`, a shell variable that was never set) is refused, naming the option:
// CLI11 reads '' as 0 for a number, and no option here means anything by an empty string.
void RefuseEmptyValues(const CLI::App& app) {
  for (const CLI::Option* option : app.get_options()) {
    for (const std::string& value : option->results()) {
      if (option->get_expected_min() > 0 && value.find_first_not_of(" \t\n") == std::string::npos) {
        throw util::InputError(fmt::format("{}: an empty value", option->get_name()));
      }
    }
  }
  for (const CLI::App* sub : app.get_subcommands()) RefuseEmptyValues(*sub);
}

}  // namespace

void SetUpApp(CLI::App& app) {
  // Before any thread starts: SIGINT/SIGTERM/SIGHUP remove staged outputs, then end the process (util/io.h).
  util::InstallSignalCleanup();
  util::GuardInputs();  // an output naming one of the run's inputs is refused (docs/robustness.md)
  // Ceres logs through glog (failed steps, rank-deficient covariances); every failure reaches the user as one line
  // from the library's own result, so glog's lines would only be noise on stderr.
  FLAGS_minloglevel = google::GLOG_FATAL;
  util::KeepAnalysisBuffersInTheHeap();  // analyses reuse their buffers instead of faulting in fresh pages
  app.set_version_flag("--version", fmt::format("topocal {} (commit {})", kVersion, BuildCommit()));
  app.require_subcommand(1);
  // Every option shows its default in --help (subcommands inherit this when they are created).
  app.option_defaults()->always_capture_default();
  // --quiet anywhere on the line (before or after the verb): no progress lines on stderr.
  auto quiet = std::make_shared<bool>(false);
  app.add_flag("--quiet", *quiet, "No progress lines on stderr (they are off anyway when stderr is not a terminal)");
  app.fallthrough();
  app.parse_complete_callback([quiet, &app] {
    RefuseEmptyValues(app);
    util::SetQuiet(*quiet);
  });
}

// A command-line mistake as one line like every other error (CLI11's own is two, without the verb): the verb it
// belongs to, CLI11's message, where to look. An unknown verb is named as such (CLI11 says "A subcommand is
// required").
namespace {

std::string UsageErrorLine(const CLI::App& app, const CLI::ParseError& e, int argc, char** argv) {
  std::string message = e.what();
  for (char& c : message) {
    if (c == '\n') c = ' ';
  }
  std::string path;
  const CLI::App* at = &app;
  for (bool deeper = true; deeper;) {
    deeper = false;
    for (const CLI::App* sub : at->get_subcommands()) {  // the parsed ones
      path += (path.empty() ? "" : " ") + sub->get_name();
      at = sub;
      deeper = true;
      break;
    }
  }
  if (path.empty() && argc > 1 && argv[1][0] != '-') {
    bool known = false;
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
      known = known || sub->get_name() == argv[1];
    }
    if (!known) return fmt::format("'{}' is not a verb (topocal --help lists them)", argv[1]);
  }
  return path.empty() ? fmt::format("{} (topocal --help)", message)
                      : fmt::format("{}: {} (topocal {} --help)", path, message, path);
}

}  // namespace

int RunApp(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    fmt::print(stderr, "topocal: {}\n", UsageErrorLine(app, e, argc, argv));
    return 2;
  } catch (const util::ConfigError& e) {
    fmt::print(stderr, "topocal: {}\n", e.what());
    return 2;
  } catch (const util::InputError& e) {
    fmt::print(stderr, "topocal: {}\n", e.what());
    return 2;
  } catch (const VerdictFailed& e) {
    fmt::print(stderr, "topocal: {}\n", e.what());
    return 3;
  } catch (const util::MeasurementRefused& e) {
    fmt::print(stderr, "topocal: {}\n", e.what());
    return 4;
  } catch (const std::exception& e) {
    fmt::print(stderr, "topocal: {}\n", e.what());
    return 1;
  }
  return 0;
}

}  // namespace topocal::tools

// The parts of every verb's --help that are the same everywhere: one runnable example (the footer) and one syntax
// for lists. Kept in one table so that a verb without an example fails tests/cli/help_test (and nobody has to edit
// thirteen files to change the wording).
#include <map>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

#include "tools/commands.h"

namespace topocal::tools {
namespace {

// Keyed by the path of the (sub)command; each is a command of README.md or docs/.
const std::map<std::string, std::string>& Examples() {
  static const std::map<std::string, std::string> examples = {
      {"design", "topocal design --config data/paper.json --out targets.csv --svg screen.svg"},
      {"simulate", "topocal simulate --config data/paper.json --sigma 6.3e-5 --out spots.csv"},
      {"sweep", "topocal sweep --config data/paper.json --correct"},
      {"reconstruct", "topocal reconstruct --config data/paper.json --image spots.png --device data/device.json "
                      "--calibration cal.yaml --truth"},
      {"render-spots", "topocal render-spots --config data/paper.json --device data/device.json --sigma 6.3e-5 "
                       "--out spots.png"},
      {"detect", "topocal detect --image spots.png --device data/device.json --config data/paper.json "
                 "--out detected.csv"},
      {"undistort", "topocal undistort --calibration cal.yaml --image view.png --out view-undistorted.png"},
      {"calibrate", "topocal calibrate --target board.yaml --images 'shots/*.png' --model brown5 --out cal.yaml"},
      {"target", "topocal target --target board.yaml --out board.svg"},
      {"render-target", "topocal render-target --target board.yaml --width 1600 --height 1200 --fx 1400 "
                        "--k1 -0.2 --distance-mm 200 --out view.png"},
      {"unit", "topocal unit calibrate --serial SN-0001 --target data/target-topographer.yaml "
               "--images 'SN-0001/target*.png' --out units/SN-0001/"},
      {"unit calibrate", "topocal unit calibrate --serial SN-0001 --target data/target-topographer.yaml "
                         "--images 'SN-0001/target*.png' --reference-sphere SN-0001/sphere.png --sphere-radius-mm 7.8 "
                         "--out units/SN-0001/"},
      {"unit calibrate-batch", "topocal unit calibrate-batch inputs/ --out units/"},
      {"harness", "topocal harness --config data/harness.json --out results/"},
      {"harness merge", "topocal harness merge --out results/ s0/ s1/ s2/"},
      {"report", "topocal report --unit units/SN-0001/ --out SN-0001.html --json SN-0001.json"},
      {"device", "topocal device calibrate --config data/paper.json --device data/device.json "
                 "--balls ball-6.5.png ball-7.8.png ball-9.0.png --radii-mm 6.5 7.8 9.0 --out unit-device.json"},
      {"device calibrate", "topocal device calibrate --config data/paper.json --device data/device.json "
                           "--balls ball-6.5.png ball-7.8.png ball-9.0.png --radii-mm 6.5 7.8 9.0 "
                           "--out unit-device.json"},
      {"fleet", "topocal fleet ingest --db fleet.sqlite --station LINE-1 units/*/"},
      {"fleet ingest", "topocal fleet ingest --db fleet.sqlite --station LINE-1 units/*/"},
      {"fleet report", "topocal fleet report --db fleet.sqlite --out fleet.html"},
      {"fleet check", "topocal fleet check --db fleet.sqlite"},
      {"fleet backup", "topocal fleet backup --db fleet.sqlite --out backups/fleet-2026-12-05.sqlite"},
      {"compare", "topocal compare visit1.json visit2.json --a-maps visit1-maps/ --b-maps visit2-maps/ "
                  "--maps change/"},
      {"export", "topocal export --calibration cal.yaml --to mrcal --out cam.cameramodel"},
      {"import", "topocal import --from mrcal cam.cameramodel --out cal.yaml"},
  };
  return examples;
}

// Lists of numbers and of parameter names take spaces or commas (--fix k3 p1 p2 == --fix k3,p1,p2;
// --ball-at 0.1 0.2 0 == --ball-at 0.1,0.2,0). Lists of files take spaces only: a comma is a legal file-name
// character, so splitting there would be a trap of its own.
bool IsFileList(const CLI::Option& o) {
  const std::string name = o.get_name();
  return o.get_positional() || name == "--balls" || name == "--images";
}

void Finish(CLI::App& cmd, const std::string& path) {
  for (CLI::Option* o : cmd.get_options()) {
    if (o->get_items_expected_max() > 1 && !IsFileList(*o)) o->delimiter(',');
    if (o->get_default_str() == "[]") o->default_str("");  // an empty list: nothing to show
    // NaN marks "not given" (the default then depends on other options, as the description says): nothing a user
    // would type.
    if (o->get_default_str() == "nan") o->default_str("");
  }
  for (CLI::App* sub : cmd.get_subcommands([](CLI::App*) { return true; })) {
    const std::string sub_path = path.empty() ? sub->get_name() : path + " " + sub->get_name();
    if (sub->get_name().empty()) {  // an option group: its options belong to `cmd`
      Finish(*sub, path);
      continue;
    }
    const auto it = Examples().find(sub_path);
    if (it == Examples().end()) throw std::logic_error(fmt::format("no --help example for '{}' (tools/help.cc)", sub_path));
    sub->footer("\nExample:\n  " + it->second + "\n\nLists: numbers and parameter names separated by spaces or "
                "commas; files by spaces.");
    Finish(*sub, sub_path);
  }
}

}  // namespace

void FinishHelp(CLI::App& app) {
  Finish(app, "");
  app.footer("\nExample:\n  topocal sweep --config data/paper.json\n\nEvery verb: topocal VERB --help (defaults, an "
             "example). Exit codes: 0 success, 1 computation failed, 2 bad input, 3 QA verdict FAIL.");
}

}  // namespace topocal::tools

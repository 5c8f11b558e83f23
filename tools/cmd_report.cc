// topocal report: the options of report/report_command.h.
#include <iostream>
#include <memory>

#include "report/report_command.h"
#include "tools/commands.h"

namespace topocal::tools {

void AddReportCommand(CLI::App& app) {
  auto a = std::make_shared<report::ReportRequest>();
  auto* cmd = app.add_subcommand("report", "QA report of a unit record: one self-contained HTML file (printable)");
  cmd->add_option("--unit", a->unit_dir, "Unit record directory written by `topocal unit calibrate` (units/SN/)")
      ->required();
  cmd->add_option("--out", a->out_path, "Output HTML file")->required();
  cmd->add_option("--json", a->json_path, "Also write the checks and verdict as JSON (docs/report.md)");
  cmd->add_option("--limits", a->limits_path, "Acceptance limits (JSON, see data/limits.json); default: built in");
  cmd->add_option("--previous", a->previous_dir, "The unit's previous record (same serial), compared on the report");
  cmd->add_option("--operator", a->sign_off.operator_name, "Sign-off: who calibrated the unit");
  cmd->add_option("--station", a->sign_off.station, "Sign-off: calibration station");
  cmd->add_option("--ball-certificate", a->sign_off.ball_certificate_id, "Sign-off: reference ball certificate id");
  cmd->add_option("--target-certificate", a->sign_off.target_certificate_id,
                  "Sign-off: calibration target certificate id");
  cmd->add_option("--ball-radius-U-mm", a->ball_radius_U_mm,
                  "Expanded uncertainty (k = 2) of the reference ball's radius from its certificate, mm (default "
                  "0.001, reported as a default)");
  cmd->callback([a] { report::RunReport(*a, std::cout); });
}

}  // namespace topocal::tools

// topocal render-spots: the options of pipeline/render_spots_command.h.
#include <iostream>
#include <memory>

#include "pipeline/render_spots_command.h"
#include "tools/commands.h"
#include "util/terminal_progress.h"

namespace topocal::tools {

void AddRenderSpotsCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("render-spots", "Render the raw sensor image of the configured cornea's spot pattern");
  auto a = std::make_shared<pipeline::RenderSpotsRequest>();
  cmd->add_option("--config", a->config_path, "Topographer configuration (JSON)")->required();
  cmd->add_option("--device", a->device_path,
                  "Device (JSON, docs/device.md): camera, distortion and screen pose (data/device.json: the nominal "
                  "unit)")
      ->required();
  cmd->add_option("--sigma", a->sigma_per_mm2,
                  "Seidel distortion coefficient sigma, mm^-2 (paper Eq. 18): the configuration's Seidel distortion "
                  "at sigma instead of the device's own");
  cmd->add_option("--out", a->out_path, "Output image (.png)")->required();
  cmd->add_option("--sphere-radius-mm", a->sphere_radius_mm,
                  "Image a reference sphere of this radius instead of the configured cornea, mm");
  cmd->add_option("--ball-at", a->ball_at_mm, "Vertex of the reference sphere: x y z, mm (default 0 0 0)")
      ->expected(3);
  cmd->add_option("--truth", a->truth_path, "Truth CSV: ring,index,x_px,y_px,x_mm,y_mm (distorted; ring 0 = glint)");
  cmd->add_option("--spot", a->spot, "Spot model: ellipse (image of the null-screen spot) or psf (point source)")
      ->check(CLI::IsMember({"ellipse", "psf"}));
  cmd->add_option("--psf-px", a->psf_px, "Gaussian PSF standard deviation, px")->check(CLI::PositiveNumber);
  cmd->add_option("--bits", a->bits, "PNG bit depth (8 or 16)")->check(CLI::IsMember({8, 16}));
  cmd->add_option("--background", a->background_dn, "Background level, DN (default 1000 / 4 for 16 / 8 bits)");
  cmd->add_option("--peak", a->peak_dn, "Exposure: spot level above background, DN (default 40000 / 160)");
  cmd->add_option("--noise", a->read_noise_dn, "Read noise standard deviation, DN (default 60 / 1)");
  cmd->add_option("--gain", a->gain_e_per_dn, "Shot noise: electrons per DN, 0 = none (default 4 / 0)");
  cmd->add_option("--seed", a->seed, "Seed of the noise, drops and glints");
  cmd->add_option("--drop", a->drop_fraction, "Fraction of spots to leave out, [0, 1)");
  cmd->add_option("--glints", a->glints, "Number of spurious blobs to add");
  cmd->add_option("--upper-lid", a->upper_lid_fraction,
                  "Fraction of the pattern's height an upper lid hides, [0, 1) (its spots left out)");
  cmd->add_option("--lower-lid", a->lower_lid_fraction, "Fraction of the pattern's height a lower lid hides, [0, 1)");
  cmd->add_option("--lid-skin", a->lid_skin_dn, "The lids' skin: level above the background, DN, textured +-25 % (0: not drawn)");
  cmd->add_option("--lashes", a->lashes, "Lash shadows hanging from the upper lid's margin, count")
      ->check(CLI::Range(0, 50));
  cmd->add_option("--iris", a->iris_dn, "Textured iris behind the pattern: mean level above the background, DN (0: none)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--defocus-rim-px", a->defocus_rim_px,
                  "Defocus growing towards the rim: PSF sigma at the pattern's radius, px (--psf-px at its centre)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--motion-blur-px", a->motion_blur_px, "The eye's movement during the exposure: smear length, px")
      ->check(CLI::Range(0.0, 100.0));
  cmd->add_option("--motion-blur-deg", a->motion_blur_deg, "Direction of the smear from the image's +u axis, degrees");
  cmd->add_option("--tear-film", a->tear_film_patches, "Tear-film break-up: dry patches (spots in them lost or smeared), count")
      ->check(CLI::Range(0, 50));
  a->log = util::LogOnStderr("topocal render-spots: ");
  cmd->callback([a] { pipeline::RunRenderSpots(*a, std::cout); });
}

}  // namespace topocal::tools

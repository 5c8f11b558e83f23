#pragma once
// What detection hands to fitting: the corners of a calibration target found in one image.
//
// Pixel convention (one for all of topocal): OpenCV's — the centre of the top-left pixel is (0, 0), x to the right,
// y down. Detectors whose native convention differs (libapriltag puts pixel centres at +0.5) convert on output.
#include <string>
#include <vector>

#include <Eigen/Core>

namespace topocal::calib {

struct CornerObservation {
  int id = 0;                  // corner identity on the target: row-major index for checkerboards,
                               // 4 * tag_id + corner (0..3) for AprilTag grids; partial views keep their ids
  Eigen::Vector2d image_px;    // sub-pixel position in the image, OpenCV pixel convention
  Eigen::Vector3d target_mm;   // the same corner on the target plane (z = 0), mm
};

struct ViewObservations {
  std::string image_path;
  int image_width = 0;
  int image_height = 0;
  std::vector<CornerObservation> corners;
};

}  // namespace topocal::calib

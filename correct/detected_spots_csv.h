#pragma once
// The detected-spots file written by `topocal detect` (schema: docs/spot-noise.md, "Detected spots file"):
//
//   ring,index,x_mm,y_mm,u_px,v_px,flags
//   4,17,0.1234567890,-0.0456789012,2137.482913,1452.003341,near_blob|saturated
//   0,3,...                                   (ring 0: a blob without identity; index = its detection number)
//
// x_mm, y_mm: the detection plane (paper frame, distorted: as the camera saw them); u_px, v_px: OpenCV pixel
// coordinates; flags: SpotFlagsText (empty when clean). Rows: identified spots (usable and excluded) by id, then the
// unassigned blobs. Missing identities are not rows: they are listed in the JSON summary.
#include <string>
#include <vector>

#include "correct/detect_and_index.h"

namespace topocal::correct {

// The file's rows in its order: identified spots (usable and excluded) by id, then the unassigned blobs. The CSV and
// the Python module's structured array (python/) are both made from them.
std::vector<LocatedSpot> DetectedSpotRows(const DetectAndIndexResult& result);

std::string DetectedSpotsCsv(const DetectAndIndexResult& result);

}  // namespace topocal::correct

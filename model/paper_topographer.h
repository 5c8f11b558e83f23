#pragma once
// The paper's topographer: the one place its nominal numbers live (Table IV and the smartphone camera of the paper's
// Section 4). Every structure that needs a default for one of them takes it from here; a real unit's values come from
// its files (configuration, camera, device).
namespace topocal::model {

inline constexpr double kPaperAMm = 5.2;               // a: pinhole to detection plane, mm
inline constexpr double kPaperMagnification = -0.065;  // M_T: transverse magnification (< 0: inverted image)
inline constexpr double kPaperPixelPitchUm = 1.12;     // the sensor's pixel pitch, um

}  // namespace topocal::model

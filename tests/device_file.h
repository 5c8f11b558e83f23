#pragma once
// A nominal device file (docs/device.md: the camera, no distortion, the screen as designed) around a camera, for
// tests that need a camera other than the bundled data/device.json's.
#include <string>

#include "model/device.h"
#include "model/topographer_camera.h"

namespace topocal::testing_cli {

inline std::string NominalDeviceText(const model::TopographerCamera& camera) {
  return model::DeviceToJson(model::NominalDevice(camera));
}

// `camera_json`: a camera object as a device file's "camera" section holds it.
inline std::string NominalDeviceText(const std::string& camera_json) {
  return NominalDeviceText(model::ParseTopographerCamera(camera_json, "test camera"));
}

}  // namespace topocal::testing_cli

#pragma once
// OpenCV's radial-tangential (Brown-Conrady) lens distortion on normalised coordinates x_n = (x - c_x) / f, the five
// distCoeffs cv::calibrateCamera fits by default, in their order k1, k2, p1, p2, k3:
//   x_d = x_n g(r^2) + 2 p1 x_n y_n + p2 (r^2 + 2 x_n^2)
//   y_d = y_n g(r^2) + p1 (r^2 + 2 y_n^2) + 2 p2 x_n y_n,      g(s) = 1 + k1 s + k2 s^2 + k3 s^3
// One entry of the lens-model list (model/lens_model.h).
#include <array>
#include <string_view>

namespace topocal::model {

// The distortion of every model of OpenCV's distCoeffs family, given its radial factor g (M::RadialFactor) and its
// tangential pair at k[2], k[3]:
//   x_d = x g(r^2) + 2 p1 x y + p2 (r^2 + 2 x^2),   y_d = y g(r^2) + p1 (r^2 + 2 y^2) + 2 p2 x y
// summed as OpenCV sums it ((radial + a) + b).
template <class M, typename T>
inline void DistortOpenCvFamily(const T* k, const T* xn, T* xd) noexcept {
  const T x = xn[0], y = xn[1];
  const T r2 = x * x + y * y;
  const T radial = M::RadialFactor(k, r2);
  const T& p1 = k[2];
  const T& p2 = k[3];
  xd[0] = x * radial + T(2) * p1 * x * y + p2 * (r2 + T(2) * x * x);
  xd[1] = y * radial + p1 * (r2 + T(2) * y * y) + T(2) * p2 * x * y;
}

struct BrownConrady {
  static constexpr std::string_view kName = "brown5";       // calibration files and --model
  static constexpr std::string_view kDeviceName = "brown";  // device files (docs/device.md)
  static constexpr std::string_view kRosName = "plumb_bob";        // ROS camera_info distortion_model
  static constexpr std::string_view kMrcalName = "LENSMODEL_OPENCV5";  // mrcal lensmodel
  static constexpr int kNumParams = 5;
  static constexpr std::array<std::string_view, kNumParams> kParameterNames = {"k1", "k2", "p1", "p2", "k3"};
  enum Index : int { kK1 = 0, kK2 = 1, kP1 = 2, kP2 = 3, kK3 = 4 };

  // g(s), s = r^2: the radial part alone maps radius r to r g(r^2).
  template <typename T>
  static T RadialFactor(const T* k, const T& s) noexcept {
    return T(1) + s * (k[kK1] + s * (k[kK2] + s * k[kK3]));
  }
  template <typename T>
  static void DistortNormalized(const T* k, const T* xn, T* xd) noexcept {
    DistortOpenCvFamily<BrownConrady>(k, xn, xd);
  }
};

}  // namespace topocal::model

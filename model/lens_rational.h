#pragma once
// OpenCV's rational lens model (CALIB_RATIONAL_MODEL), the first eight distCoeffs k1, k2, p1, p2, k3, k4, k5, k6:
// Brown-Conrady (model/lens_brown_conrady.h) with the radial factor a ratio of two cubics in s = r^2,
//   g(s) = (1 + k1 s + k2 s^2 + k3 s^3) / (1 + k4 s + k5 s^2 + k6 s^3),
// for wide-angle lenses whose distortion a polynomial cannot follow to the corners. k4 = k5 = k6 = 0 is Brown.
// One entry of the lens-model list (model/lens_model.h).
#include <array>
#include <string_view>

#include "model/lens_brown_conrady.h"

namespace topocal::model {

struct RationalPolynomial {
  static constexpr std::string_view kName = "rational8";
  static constexpr std::string_view kDeviceName = "rational8";
  static constexpr std::string_view kRosName = "rational_polynomial";        // ROS camera_info distortion_model
  static constexpr std::string_view kMrcalName = "LENSMODEL_OPENCV8";  // mrcal lensmodel
  static constexpr int kNumParams = 8;
  static constexpr std::array<std::string_view, kNumParams> kParameterNames = {"k1", "k2", "p1", "p2",
                                                                               "k3", "k4", "k5", "k6"};
  enum Index : int { kK1 = 0, kK2 = 1, kP1 = 2, kP2 = 3, kK3 = 4, kK4 = 5, kK5 = 6, kK6 = 7 };

  template <typename T>
  static T RadialFactor(const T* k, const T& s) noexcept {
    return (T(1) + s * (k[kK1] + s * (k[kK2] + s * k[kK3]))) / (T(1) + s * (k[kK4] + s * (k[kK5] + s * k[kK6])));
  }
  template <typename T>
  static void DistortNormalized(const T* k, const T* xn, T* xd) noexcept {
    DistortOpenCvFamily<RationalPolynomial>(k, xn, xd);
  }
};

}  // namespace topocal::model

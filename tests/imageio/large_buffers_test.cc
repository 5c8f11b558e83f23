// Image-sized buffers on huge pages (imageio/large_buffers.h): where they come from changes, what a cv::Mat holds and
// how it behaves do not.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>
#include <opencv2/core.hpp>

#include "imageio/large_buffers.h"

namespace topocal::imageio {
namespace {

constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;

bool OnAHugePageBoundary(const void* p) { return reinterpret_cast<std::uintptr_t>(p) % kHugePage == 0; }

TEST(LargeBuffers, AFrameIsOneAlignedMappingThatBehavesAsOpenCvsOwn) {
  UseHugePagesForImageBuffers();
  {
    cv::Mat frame(3000, 4000, CV_16UC1);
    EXPECT_TRUE(OnAHugePageBoundary(frame.data));  // every page of it can be huge
    EXPECT_TRUE(frame.isContinuous());
    EXPECT_EQ(frame.step[0], 8000u);
    EXPECT_EQ(frame.step[1], 2u);
    frame.setTo(1000);
    frame(cv::Rect(10, 20, 30, 40)).setTo(7);
    EXPECT_EQ(cv::countNonZero(frame != 1000), 30 * 40);
    EXPECT_EQ(frame.at<std::uint16_t>(2999, 3999), 1000);
    // Shared, copied, cloned, converted and released as OpenCV's own buffers are.
    cv::Mat shared = frame;
    const cv::Mat copy = frame.clone();
    frame.release();
    EXPECT_EQ(shared.at<std::uint16_t>(25, 15), 7);
    EXPECT_EQ(cv::norm(shared, copy, cv::NORM_INF), 0.0);
    cv::Mat eight;
    copy.convertTo(eight, CV_8U, 0.1);
    EXPECT_TRUE(OnAHugePageBoundary(eight.data));  // 12 MB
    EXPECT_EQ(eight.at<std::uint8_t>(0, 0), 100);
    // Three dimensions: the same continuous layout.
    const int sizes[3] = {64, 256, 256};
    cv::Mat volume(3, sizes, CV_32FC1, cv::Scalar(2.5f));
    EXPECT_TRUE(OnAHugePageBoundary(volume.data));
    EXPECT_EQ(volume.step[0], 256u * 256u * 4u);
    EXPECT_EQ(volume.step[1], 256u * 4u);
    EXPECT_EQ(volume.at<float>(63, 255, 255), 2.5f);
  }
  // Small buffers and the caller's own stay OpenCV's.
  cv::Mat small(10, 10, CV_8UC1, cv::Scalar(3));
  EXPECT_EQ(cv::sum(small)[0], 300.0);
  std::vector<std::uint16_t> pixels(3000 * 4000, 5);
  const cv::Mat wrapped(3000, 4000, CV_16UC1, pixels.data());
  EXPECT_EQ(wrapped.data, reinterpret_cast<uchar*>(pixels.data()));
  EXPECT_EQ(cv::sum(wrapped)[0], 5.0 * 3000 * 4000);
}

}  // namespace
}  // namespace topocal::imageio

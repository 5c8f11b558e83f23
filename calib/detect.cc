#include "calib/detect.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <string_view>
#include <opencv2/imgproc.hpp>

#include "calib/apriltag_detector.h"
#include "calib/charuco_detector.h"
#include "calib/checkerboard_detector.h"
#include "calib/kalibr_grid_detector.h"
#include "imageio/image_file.h"
#include "util/io.h"
#include "util/parallel.h"
#include "util/sha256.h"

namespace topocal::calib {

bool DetectionOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (!std::isfinite(saddle_window_sigma_px) || saddle_window_sigma_px < 0) {
    return fail("saddle window sigma must be >= 0 px (0 = automatic)");
  }
  if (max_hamming < 0 || max_hamming > 3) return fail("max hamming must be 0..3");
  if (!std::isfinite(min_decision_margin) || min_decision_margin < 0) return fail("min decision margin must be >= 0");
  if (!std::isfinite(quad_decimate) || quad_decimate < 1) return fail("quad decimate must be >= 1");
  if (min_corners < 4) return fail("min corners must be at least 4");
  return true;
}

DetectionResult DetectTargetDetailed(const TargetDescription& target, const cv::Mat& image,
                                     const DetectionOptions& options) {
  DetectionResult result;
  if (!options.IsValid(&result.message)) return result;
  if (image.empty()) {
    result.message = "empty image";
    return result;
  }
  cv::Mat gray;
  if (image.type() == CV_8UC1) {
    gray = image;
  } else if (image.type() == CV_8UC3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.type() == CV_8UC4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else {
    result.message = "unsupported image type (need 8-bit grey, BGR or BGRA)";
    return result;
  }

  ViewObservations view;
  view.image_width = gray.cols;
  view.image_height = gray.rows;
  if (const auto* board = std::get_if<CheckerboardLayout>(&target.layout)) {
    const auto corners = DetectCheckerboardCorners(gray, *board, options, &result.message);
    if (!corners) return result;
    for (size_t id = 0; id < corners->corners_px.size(); ++id) {
      if (!corners->found[id]) continue;
      view.corners.push_back({static_cast<int>(id), corners->corners_px[id], *target.CornerMm(static_cast<int>(id))});
    }
    result.reasons = corners->reasons;
    result.message = fmt::format("{} corners", view.corners.size());
    if (!corners->reasons.empty()) result.message += fmt::format(" ({} left out)", corners->reasons.size());
    if (corners->beyond_frame > 0) {
      result.message += fmt::format(" (board cut by the frame: {} corners beyond it)", corners->beyond_frame);
    }
  } else if (const auto* charuco = std::get_if<CharucoLayout>(&target.layout)) {
    const CharucoDetections found = DetectCharuco(gray, *charuco, options);
    result.reasons = found.reasons;
    result.message = found.message;
    for (const auto& [id, px] : found.corners) view.corners.push_back({id, px, *target.CornerMm(id)});
  } else {
    const auto& grid = std::get<AprilGridLayout>(target.layout);
    const AprilGridDetections tags =
        grid.KalibrLayout() ? DetectKalibrAprilGrid(gray, grid, options) : DetectAprilGrid(gray, grid, options);
    result.tags_detected = static_cast<int>(tags.tags.size());
    result.tags_rejected = tags.rejected;
    result.reasons = tags.reasons;
    result.message = tags.message;
    for (const auto& tag : tags.tags) {
      for (int k = 0; k < 4; ++k) {
        if (!tag.corner_found[static_cast<size_t>(k)]) continue;
        const int id = 4 * tag.tag_index + k;
        view.corners.push_back({id, tag.corners_px[static_cast<size_t>(k)], *target.CornerMm(id)});
      }
    }
  }
  if (static_cast<int>(view.corners.size()) < options.min_corners) {
    result.message = fmt::format("too few corners ({}; {})", view.corners.size(), result.message);
    return result;
  }
  result.view = std::move(view);
  return result;
}

std::optional<ViewObservations> DetectTarget(const TargetDescription& target, const cv::Mat& image,
                                             const DetectionOptions& options) {
  return DetectTargetDetailed(target, image, options).view;
}

std::optional<ViewObservations> DetectTargetInFile(const TargetDescription& target, const std::string& image_path,
                                                   const DetectionOptions& options) {
  const cv::Mat image = imageio::ReadImage(image_path, imageio::Channels::kGrey);
  auto view = DetectTarget(target, image, options);
  if (view) view->image_path = image_path;
  return view;
}

namespace {

// The pixels' digest with the image's size: one capture under two names (a copy, or a JPEG and its PNG) has the same.
std::string PixelDigest(const cv::Mat& grey) {
  const cv::Mat flat = grey.isContinuous() ? grey : grey.clone();
  const std::string_view bytes(reinterpret_cast<const char*>(flat.data), flat.total() * flat.elemSize());
  return fmt::format("{}x{}:{}", flat.cols, flat.rows, util::Sha256Hex(bytes));
}

// The same capture given twice is no new view, yet each copy would shrink the reported standard deviations by
// another sqrt(2): every repeat after the first is skipped with a reason naming the first (as ball images are).
void SkipRepeatedImages(const std::vector<std::string>& pixel_digests, std::vector<FileDetection>& out) {
  std::map<std::string, size_t> first;
  for (size_t i = 0; i < out.size(); ++i) {
    if (pixel_digests[i].empty()) continue;
    const auto [it, inserted] = first.try_emplace(pixel_digests[i], i);
    if (inserted) continue;
    out[i].skipped = fmt::format("the same image as {} (identical pixels): no new view", out[it->second].path);
    out[i].detection.view.reset();
  }
}

}  // namespace

std::vector<FileDetection> DetectTargetInFiles(const TargetDescription& target, const std::vector<std::string>& paths,
                                               const FileSetOptions& options) {
  std::vector<FileDetection> out(paths.size());
  std::vector<std::string> pixel_digests(paths.size());
  std::mutex callback_mutex;
  // Each image is read, detected and released inside its own task: at most `jobs` images are in memory at once.
  util::ParallelFor(paths.size(), options.jobs, [&](size_t i) {
    FileDetection& f = out[i];
    f.path = paths[i];
    cv::Mat image;
    try {
      image = imageio::ReadImage(f.path, imageio::Channels::kGrey);
    } catch (const util::InputError& e) {
      // The loader's line starts with the path, which the caller prints in front of the reason already.
      const std::string what = e.what();
      f.skipped = what.rfind(f.path + ": ", 0) == 0 ? what.substr(f.path.size() + 2) : what;
    }
    if (!image.empty()) {
      pixel_digests[i] = PixelDigest(image);
      f.width_px = image.cols;
      f.height_px = image.rows;
      f.detection = DetectTargetDetailed(target, image, options.detection);
      if (f.detection.view) f.detection.view->image_path = f.path;
    }
    if (options.on_done) {
      const std::lock_guard lock(callback_mutex);
      options.on_done(i, f);
    }
  });
  SkipRepeatedImages(pixel_digests, out);
  if (options.require_same_size) {
    // The camera's size is the one most views with a target share (ties: the earliest such view). Taking the first
    // readable image instead let one stray picture (another camera, a screenshot, an image without the target)
    // disqualify every real view: the 13 opencv-doc photos came with a 612 x 459 left.jpg sorted first.
    std::map<std::pair<int, int>, std::pair<int, size_t>> sizes;  // (w, h) -> (views with a target, first index)
    for (size_t i = 0; i < out.size(); ++i) {
      if (!out[i].skipped.empty() || !out[i].detection.view) continue;
      auto [it, inserted] = sizes.try_emplace({out[i].width_px, out[i].height_px}, 0, i);
      ++it->second.first;
    }
    if (!sizes.empty()) {
      const auto best = std::max_element(sizes.begin(), sizes.end(), [](const auto& a, const auto& b) {
        return a.second.first != b.second.first ? a.second.first < b.second.first : a.second.second > b.second.second;
      });
      const auto [w, h] = best->first;
      const int views = best->second.first;
      for (auto& f : out) {
        if (!f.skipped.empty() || f.width_px <= 0 || (f.width_px == w && f.height_px == h)) continue;
        f.skipped = fmt::format("{} x {} px, not the {} x {} px of the {} view(s) with a target (one camera, one size)",
                                f.width_px, f.height_px, w, h, views);
        f.detection.view.reset();
      }
    }
  }
  return out;
}

}  // namespace topocal::calib

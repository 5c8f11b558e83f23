#pragma once
// Detection entry point: find the corners of a calibration target in one grey image.
//
//   TargetDescription target = LoadTargetDescription("board.yaml");
//   std::optional<ViewObservations> view = DetectTargetInFile(target, "img01.png", DetectionOptions{});
//   if (!view) { /* no usable target in this image: list it and skip it */ }
//
// Checkerboards: OpenCV finds the board (cv::findChessboardCornersSB, then cv::findChessboardCorners as fallback),
// and topocal refines every corner with a saddle-point fit (calib/corner_refinement.h); the whole board must be
// visible. AprilTag grids in Kalibr's layout (tagBorderBits 2, the default): OpenCV aruco and libapriltag (its
// tag36h11 codes behind a 2-cell border) both search, each tag corner is refined as an X-junction
// (calib/kalibr_grid_detector.h). 1-cell-border grids: libapriltag 3 finds tag36h11 tags; tags with hamming
// distance > max_hamming, a decision margin below min_decision_margin, or an id not on the grid are dropped; each
// tag's corners are refined by fitting its four edges. Partial views keep their
// corner ids (4 * (tag id - firstTagId) + k); every dropped tag or corner has a line in DetectionResult::reasons.
// All pixel coordinates follow OpenCV's convention (calib/observations.h); libapriltag's are converted.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "calib/observations.h"
#include "calib/target.h"

namespace topocal::calib {

// Checkerboards: kSaddle and kOpenCvSubPix choose the refinement. AprilTag grids: both mean topocal's tag-edge
// fit (calib/apriltag_detector.h); kNone keeps libapriltag's corners (converted to OpenCV's pixel convention).
enum class CornerRefinement {
  kSaddle,         // topocal's iterated, Gaussian-weighted quadratic saddle fit (checkerboards; default)
  kOpenCvSubPix,   // cv::cornerSubPix with an 11 x 11 window: OpenCV's usual call, for comparison
  kNone,           // the detector's own corners
};

struct DetectionOptions {
  CornerRefinement refinement = CornerRefinement::kSaddle;
  // Checkerboard: weight window of the saddle fit (Gaussian sigma, px); 0 = automatic from the corner spacing.
  double saddle_window_sigma_px = 0.0;
  // AprilTag filters.
  int max_hamming = 0;                  // corrected bits accepted (0: only exact codes)
  double min_decision_margin = 25.0;    // libapriltag's decision margin (mean bit contrast, grey levels)
  double quad_decimate = 1.0;           // libapriltag decimation; 1 = full resolution
  // A view with fewer corners than this is "not found" (a homography needs 4 points).
  int min_corners = 4;

  bool IsValid(std::string* why) const;
};

// What the detector found, with diagnostics for the caller to print. `view` is empty when nothing usable was found.
struct DetectionResult {
  std::optional<ViewObservations> view;
  std::string message;      // why nothing was found, or a one-line summary ("54 corners", "23/24 tags")
  int tags_detected = 0;    // AprilTag grids: tags kept after filtering
  int tags_rejected = 0;    // AprilTag grids: tags dropped by the filters
  std::vector<std::string> reasons;  // one line per rejected tag or left-out corner, for the user
};

// Detects the target in an 8-bit grey (or BGR, converted) image. Never throws for image content; an empty image,
// an unsupported type or invalid options give an empty result with a message.
DetectionResult DetectTargetDetailed(const TargetDescription& target, const cv::Mat& image,
                                     const DetectionOptions& options = {});
std::optional<ViewObservations> DetectTarget(const TargetDescription& target, const cv::Mat& image,
                                             const DetectionOptions& options = {});
// Reads the image (any format cv::imread knows) and detects; sets image_path. Throws util::InputError naming the
// file if it cannot be read as an image.
std::optional<ViewObservations> DetectTargetInFile(const TargetDescription& target, const std::string& image_path,
                                                   const DetectionOptions& options = {});

// One image of a set: what the detector made of it, or why it was not used.
struct FileDetection {
  std::string path;
  DetectionResult detection;  // detection.view is set (with image_path) when the target was found
  std::string skipped;  // non-empty when the image was not used: unreadable, a repeat of an earlier one, not the set's size
  int width_px = 0, height_px = 0;
};

struct FileSetOptions {
  DetectionOptions detection;
  int jobs = 0;  // images detected at once; 0 = every available core. The results do not depend on it.
  // Views of one camera have one size: the size most images with a target share (ties: the earliest) is the
  // camera's, and images of another size are skipped with a reason naming both sizes.
  bool require_same_size = true;
  // Called once per image as its detection finishes (in completion order, one call at a time), for progress lines.
  std::function<void(size_t index, const FileDetection&)> on_done;
};

// Reads and detects every image of a calibration set, several at once. Results are in the order of `paths` and
// identical whatever `jobs`. Never throws for an image's content or an unreadable file: those are skipped with
// their reason; the caller decides whether enough views remain.
std::vector<FileDetection> DetectTargetInFiles(const TargetDescription& target, const std::vector<std::string>& paths,
                                               const FileSetOptions& options = {});

}  // namespace topocal::calib

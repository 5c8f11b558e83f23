#include "pipeline/unit_workflow.h"

#include "pipeline/measurement_uncertainty.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <tuple>

#include "calib/calibrate.h"
#include "calib/detect.h"
#include "calib/parameter_range.h"
#include "calib/target.h"
#include "imageio/image_file.h"
#include "model/config.h"
#include "model/device.h"
#include "model/topographer_camera.h"
#include "pipeline/detection_plane.h"
#include "pipeline/device_calibration.h"
#include "pipeline/device_verification.h"
#include "pipeline/measurement_uncertainty.h"
#include "pipeline/unit_verification.h"
#include "util/file_glob.h"
#include "util/io.h"
#include "util/json_section.h"
#include "util/median.h"
#include "util/sha256.h"
#include "util/utc_date.h"

namespace topocal::pipeline {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr size_t kMaxSerialLength = 64;

// Largest displacement (um on the detection plane, and px) the calibrated distortion gives a point within
// `radius_mm` of the axis, sampled on a polar grid.
std::pair<double, double> MaxDisplacement(const model::Distortion& d, double radius_mm, double pitch_mm) {
  constexpr int kRings = 20, kMeridians = 72;
  double max_mm = 0;
  for (int i = 1; i <= kRings; ++i) {
    const double r = radius_mm * i / kRings;
    for (int j = 0; j < kMeridians; ++j) {
      const double t = 2 * M_PI * j / kMeridians;
      const Eigen::Vector2d p(r * std::cos(t), r * std::sin(t));
      max_mm = std::max(max_mm, (model::Distort(d, p) - p).norm());
    }
  }
  return {max_mm * 1000.0, max_mm / pitch_mm};
}

// The inputs, read and checked before any work, with their digests for the record.
struct LoadedInputs {
  model::Config config;
  model::TopographerCamera camera;
  calib::TargetDescription target;
  calib::CalibrationOptions options;
  std::vector<imageio::ImageBytes> view_bytes;  // the calibration images as read for their digests, decoded by CalibrateViews
  imageio::ImageBytes sphere_bytes;  // the reference sphere as read (empty without one), decoded by StartSphere
  size_t sphere_provenance = 0;  // its entry in `provenance`, whose digest StartSphere computes
  std::vector<imageio::ImageBytes> repeat_bytes;  // the sphere's repeated images as read, decoded one at a time
  model::Device nominal_device;
  std::vector<pipeline::BallImage> balls;  // empty: no device stage
  std::vector<UnitInputDigest> provenance;
};

// Whether an image still to be decoded needs OpenCV's codecs (a JPEG, a palette PNG, ...).
bool NeedsCodecs(const LoadedInputs& in) {
  const auto needs = [](const imageio::ImageBytes& b) { return !imageio::DecodesWithoutCodecs(b.view()); };
  return std::any_of(in.view_bytes.begin(), in.view_bytes.end(), needs) ||
         (!in.sphere_bytes.view().empty() && needs(in.sphere_bytes)) ||
         std::any_of(in.repeat_bytes.begin(), in.repeat_bytes.end(), needs);
}

void CheckImageSize(const cv::Mat& image, const std::string& path, const LoadedInputs& in, const UnitRequest& r) {
  imageio::RequireSize(image, path, in.camera.width_px, in.camera.height_px, r.device);
}

// The record's folder is named after the unit (a record of SN-0111 in units/SN-9999/ would be filed under another
// unit), and a record already there is replaced only when asked, its predecessor kept.
void RequireRecordPlace(const UnitRequest& r) {
  fs::path out = fs::path(r.out).lexically_normal();
  if (out.filename().empty() && out.has_parent_path()) out = out.parent_path();
  if (out.filename().string() != r.serial) {
    throw util::InputError(fmt::format("--out {}: the record's folder must be named after the unit: .../{}/", r.out,
                                       r.serial));
  }
  if (!r.keep_history && fs::exists(out / "unit.json")) {
    throw util::InputError(fmt::format("--out {}: unit {} already has a record there; --force keeps it under {} and "
                                       "writes the new one",
                                       r.out, r.serial, RecordHistoryDir(out).string()));
  }
}

// The request's own consistency, before any file is read.
void ValidateRequest(const UnitRequest& r) {
  if (!IsValidSerial(r.serial)) {
    throw util::InputError(fmt::format("--serial '{}': use 1-{} characters of A-Z a-z 0-9 . _ - (not starting with .)",
                                       r.serial, kMaxSerialLength));
  }
  if (r.out.empty()) throw util::InputError("--out: the record directory is required");
  if (r.reference_sphere.empty() != (r.sphere_radius_mm == 0)) {
    throw util::InputError("--reference-sphere and --sphere-radius-mm go together");
  }
  if (!r.sphere_repeats.empty() && r.reference_sphere.empty()) {
    throw util::InputError("--sphere-repeats: repeated images of the reference sphere go with --reference-sphere");
  }
  // Re-checked, as the request may not come from Parse.
  if (!UncertaintySetting::FromName(r.uncertainty.MethodName(), r.uncertainty.draws)) {
    throw util::InputError("--uncertainty: " + UncertaintySetting::WhyNot(r.uncertainty.MethodName(),
                                                                          r.uncertainty.draws));
  }
  if (r.images.empty()) throw util::InputError("--images: no image given");
  if (r.balls.size() != r.ball_radii_mm.size()) {
    throw util::InputError(fmt::format("--radii-mm: {} radii for {} ball images (one certified radius per image)",
                                       r.ball_radii_mm.size(), r.balls.size()));
  }
  if (fs::exists(r.out) && !fs::exists(fs::path(r.out) / "unit.json")) {
    throw util::InputError(fmt::format("--out {}: exists and is not a unit record; not overwriting it", r.out));
  }
  RequireRecordPlace(r);
}

// The calibration's options from the request and the topographer it calibrates.
void SetCalibrationOptions(const UnitRequest& r, LoadedInputs* loaded) {
  LoadedInputs& in = *loaded;
  const auto model_kind = calib::ParseDistortionModel(r.model);
  if (!model_kind) {
    throw util::InputError(fmt::format("--model: '{}' is not one of {}", r.model, calib::DistortionModelNames()));
  }
  auto& o = in.options;
  o.model = *model_kind;
  o.fit_distortion_centre = r.fit_centre;
  o.fixed = {r.fixed.begin(), r.fixed.end()};
  o.fixed_aspect_ratio = r.fixed_aspect_ratio;
  // The topographer's geometry: the lens and sensor from the camera description, the target at the cornea position.
  o.focal_mm = in.camera.a_mm;
  o.pixel_pitch_um = in.camera.pixel_pitch_um;
  o.distance_mm = in.config.topographer.b_mm;
  o.magnification = in.config.distortion.magnification;
  const auto names = calib::CameraParameterNames(o.model);
  for (const auto& f : r.fixed) {
    if (std::find(names.begin(), names.end(), f) == names.end()) {
      throw util::InputError(fmt::format("--fix: '{}' is not a camera parameter ({})", f, fmt::join(names, " ")));
    }
  }
  std::string why;
  if (!o.IsValid(&why)) throw util::InputError(why);
  if (r.fixed_aspect_ratio > 0 && r.images.size() == 1) {
    throw util::InputError("--fix-aspect: applies to multi-view fits; a single view already holds fx = fy");
  }
}

LoadedInputs LoadInputs(const UnitRequest& r) {
  ValidateRequest(r);
  LoadedInputs in;
  in.config = model::LoadConfig(r.config);
  in.nominal_device = model::LoadDevice(r.device).device;
  in.camera = in.nominal_device.camera;
  in.target = calib::LoadTargetDescription(r.target);
  SetCalibrationOptions(r, &in);

  const auto add = [&](const std::string& role, const std::string& path) {
    const auto name = r.input_names.find(path);
    in.provenance.push_back({role, name == r.input_names.end() ? path : name->second, util::Sha256HexOfFile(path)});
  };
  // An image is read once: its digest and its decoding come from the same bytes, on two threads.
  const auto add_image = [&](const std::string& role, const std::string& path) -> cv::Mat {
    const imageio::ImageBytes bytes = imageio::ReadImageBytes(path);
    auto digest = std::async(std::launch::async, [&bytes] { return util::Sha256Hex(bytes); });
    cv::Mat image = imageio::DecodeImage(bytes, imageio::Channels::kAsStored, path);
    in.provenance.push_back({role, path, digest.get()});
    return image;
  };
  add("config", r.config);
  add("device", r.device);
  add("target", r.target);
  for (const auto& path : r.images) {
    in.view_bytes.push_back(imageio::ReadImageBytes(path));
    in.provenance.push_back({"image", path, util::Sha256Hex(in.view_bytes.back())});
  }
  if (!r.reference_sphere.empty()) {
    in.sphere_bytes = imageio::ReadImageBytes(r.reference_sphere);
    in.sphere_provenance = in.provenance.size();
    in.provenance.push_back({"reference_sphere", r.reference_sphere, ""});
  }
  for (const auto& path : r.sphere_repeats) {
    in.repeat_bytes.push_back(imageio::ReadImageBytes(path));
    in.provenance.push_back({"reference_sphere_repeat", path, util::Sha256Hex(in.repeat_bytes.back())});
  }
  for (size_t i = 0; i < r.balls.size(); ++i) {
    // Checked before the image is read (pipeline::CalibrateDevice checks it too).
    if (!(r.ball_radii_mm[i] >= kMinBallRadiusMm && r.ball_radii_mm[i] <= kMaxBallRadiusMm)) {
      throw util::InputError(fmt::format("--radii-mm: {} for {} is not a reference-ball radius ({}-{} mm)",
                                         r.ball_radii_mm[i], r.balls[i], kMinBallRadiusMm, kMaxBallRadiusMm));
    }
    pipeline::BallImage b{r.balls[i], add_image("ball", r.balls[i]), r.ball_radii_mm[i]};
    CheckImageSize(b.image, r.balls[i], in, r);
    in.balls.push_back(std::move(b));
  }
  return in;
}

// An error of the reference sphere's check (or of a repeated image of it), named by its image: bad input stays bad
// input (exit 2), a computation that failed names the unit too (exit 1).
[[noreturn]] void RethrowForImage(const std::exception_ptr& error, const std::string& path, const std::string& serial) {
  try {
    std::rethrow_exception(error);
  } catch (const util::InputError& e) {
    throw util::InputError(fmt::format("{}: {}", path, e.what()));
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: {}: {}", serial, path, e.what()));
  }
}

// Each repeated image of the reference sphere measured as the sphere was, without Monte Carlo draws (only the
// corrected numbers are kept), after the sphere's own numbers. The images are decoded one at a time.
SphereRepeats MeasureSphereRepeats(const UnitRequest& r, LoadedInputs& in, const UnitCalibration& unit,
                                   const SphereVerification& sphere) {
  SphereRepeats out;
  const auto keep = [&out](const SphereVerification& s) {
    out.radius_mm.push_back(s.corrected.numbers.radius_mm);
    out.central_axial_power_D.push_back(s.corrected.numbers.central_axial_power_D);
  };
  keep(sphere);
  for (size_t i = 0; i < r.sphere_repeats.size(); ++i) {
    const std::string& path = r.sphere_repeats[i];
    try {
      const imageio::ImageBytes bytes = std::move(in.repeat_bytes[i]);
      const cv::Mat image = imageio::DecodeImage(bytes, imageio::Channels::kAsStored, path);
      CheckImageSize(image, path, in, r);
      const CheckOptions without_uncertainty{{UncertaintySetting::Method::kNone, 0}, r.seed, 1};
      keep(VerifyOnReferenceSphere(image, r.sphere_radius_mm, unit, in.camera, in.config, without_uncertainty));
    } catch (...) {
      RethrowForImage(std::current_exception(), path, r.serial);
    }
  }
  return out;
}

// The reference sphere as the camera saw it: decoded, its size checked and its spots detected and identified. None of
// it needs the calibration, so it runs on a thread of its own while the camera is calibrated (the 17 MB
// 16-bit PNG takes longer to decode than the target image takes to decode, detect and calibrate).
struct SphereImage {
  cv::Mat image;
  std::optional<SphereVerification> detected;
  std::exception_ptr detection_error;  // DetectReferenceSphere's, rethrown where the check would have thrown it
};

// Decoding or size errors are the future's exception (bad input, reported before a calibration failure, as when the
// sphere was decoded first); the bytes are released once decoded.
std::future<SphereImage> StartSphere(const UnitRequest& r, LoadedInputs& in) {
  if (r.reference_sphere.empty()) return {};
  return std::async(std::launch::async, [&r, &in] {
    SphereImage s;
    {
      const imageio::ImageBytes bytes = std::move(in.sphere_bytes);
      auto digest = std::async(std::launch::async, [&bytes] { return util::Sha256Hex(bytes); });
      s.image = imageio::DecodeImage(bytes, imageio::Channels::kAsStored, r.reference_sphere);
      in.provenance[in.sphere_provenance].sha256 = digest.get();
    }
    CheckImageSize(s.image, r.reference_sphere, in, r);
    try {
      s.detected = DetectReferenceSphere(s.image, r.sphere_radius_mm, in.camera, in.config);
    } catch (...) {
      s.detection_error = std::current_exception();
    }
    return s;
  });
}

// The device from the balls and, in the same fit, the target views the camera calibration used (their corners through
// the same camera: with a lens model, every coefficient is fitted with the screen pose).
std::optional<UnitDeviceStage> CalibrateDeviceStage(const UnitRequest& r, const LoadedInputs& in,
                                                    const UnitCameraCalibration& camera, const cv::Mat& sphere_image,
                                                    const DetectionPlaneModel& lens) {
  if (in.balls.empty()) return std::nullopt;
  UnitDeviceStage d;
  try {
    d.calibration = pipeline::CalibrateDevice(in.balls, in.nominal_device, in.config, {}, camera.views_used);
  } catch (const util::InputError& e) {  // bad input stays bad input (it is a runtime_error too)
    throw util::InputError(fmt::format("{}: {}", r.serial, e.what()));
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: {}", r.serial, e.what()));
  }
  if (!d.calibration.fit.ok) {
    throw std::runtime_error(fmt::format("{}: device calibration failed: {}", r.serial, d.calibration.fit.message));
  }
  d.lens_only = in.nominal_device;
  d.lens_only.camera.pixel_aspect = lens.camera.pixel_aspect;  // the lens calibration's fx / fy
  d.lens_only.distortion = lens.distortion;
  const auto& device = d.calibration.fit.device;
  try {
    if (!sphere_image.empty()) {
      d.held_out = pipeline::VerifyHeldOutBall(sphere_image, r.sphere_radius_mm, in.nominal_device, d.lens_only,
                                               device, in.config);
    }
    d.paper = pipeline::PaperCorneaThroughDevice(in.nominal_device, d.lens_only, device, in.config);
  } catch (const util::InputError& e) {
    throw util::InputError(fmt::format("{}: {}", r.reference_sphere, e.what()));
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: {}", r.serial, e.what()));
  }
  return d;
}

UnitCameraCalibration CalibrateViews(const UnitRequest& r, LoadedInputs& in,
                           const std::function<void(const std::string&)>& log) {
  UnitCameraCalibration c;
  std::vector<calib::ViewObservations> views;
  for (size_t v = 0; v < r.images.size(); ++v) {
    const std::string& path = r.images[v];
    const cv::Mat image = imageio::DecodeImage(in.view_bytes[v], imageio::Channels::kGrey, path);
    in.view_bytes[v] = {};  // decoded: the bytes are no longer needed
    CheckImageSize(image, path, in, r);
    const auto found = calib::DetectTargetDetailed(in.target, image);
    if (!found.view) {
      log(fmt::format("{}: skipping {}: no target found{}", r.serial, path,
                      found.message.empty() ? "" : ": " + found.message));
      continue;
    }
    views.push_back(*found.view);
    views.back().image_path = path;
    c.view_paths.push_back(path);
  }
  if (views.empty()) {
    throw std::runtime_error(
        fmt::format("{}: no target found in any image (target description {})", r.serial, r.target));
  }
  c.single_view = r.images.size() == 1;
  c.result = c.single_view ? calib::CalibrateSingleView(views[0], in.options)
                           : calib::CalibrateMultiView(views, in.options);
  for (const auto& s : c.result.skipped_views) {
    log(fmt::format("{}: not used {}: {}", r.serial, c.view_paths[static_cast<size_t>(s.view)], s.reason));
  }
  for (const int v : c.result.views_used) c.views_used.push_back(views[static_cast<size_t>(v)]);
  if (!c.result.ok()) {
    throw std::runtime_error(fmt::format("{}: calibration failed ({}): {}", r.serial,
                                         calib::ToString(c.result.status), c.result.message));
  }
  // A parameter the views do not bound would ship as a number that means nothing: refused unless asked for.
  if (const auto undetermined = calib::UndeterminedParameters(c.result); !undetermined.empty()) {
    if (!r.allow_undetermined) {
      throw util::InputError(fmt::format("{}: {} (or --allow-undetermined to record it as undetermined)", r.serial,
                                         calib::UndeterminedMessage(undetermined)));
    }
    log(fmt::format("{}: recorded as undetermined: {}", r.serial, calib::UndeterminedMessage(undetermined)));
  }
  return c;
}

DistortionField MeasureDistortionField(const model::CameraModel& calibrated, const LoadedInputs& in,
                                       const std::string& serial) {
  const auto on_plane = pipeline::DetectionPlaneModelOf(calibrated, in.camera);
  if (!on_plane.ok) throw std::runtime_error(fmt::format("{}: {}", serial, on_plane.message));
  const model::Distortion* distortion = &on_plane.distortion;
  const auto& cfg = in.config;
  const auto design = model::DesignNullScreen(cfg.ideal_image, cfg.topographer);
  const auto ideal =
      model::SynthesizeImage(model::Biconic{cfg.cornea}, model::Topographer{cfg.topographer}, design.targets);
  DistortionField f;
  for (const auto& s : ideal.spots) f.field_radius_mm = std::max(f.field_radius_mm, s.position_mm.norm());
  std::tie(f.max_um, f.max_px) = MaxDisplacement(*distortion, f.field_radius_mm, in.camera.PitchMm());
  return f;
}

}  // namespace

std::filesystem::path RecordHistoryDir(const std::filesystem::path& record) {
  const fs::path parent = record.has_parent_path() ? record.parent_path() : fs::path(".");
  return parent / ".history" / record.filename();
}

std::vector<std::string> UnitSummary(const UnitResult& unit) {
  const auto& r = unit.request;
  const auto& c = unit.calibration;
  const auto& field = unit.field;
  const auto& sphere = unit.sphere;
  const auto& paper = unit.paper;
  const auto& device = unit.device;
  const auto& result = c.result;
  std::vector<std::string> lines;
  lines.push_back(fmt::format("{}: {} {} calibration, {} view(s), {} corners, rms {:.4f} px{}", r.serial,
                              calib::ToString(result.model), c.single_view ? "single-view" : "multi-view",
                              result.views_used.size(), result.corners_used, result.rms_px,
                              result.seidel ? fmt::format(", sigma {:.6g} mm^-2 +- {:.2g} (U, k = 2)",
                                                          result.seidel->sigma_per_mm2,
                                                          2.0 * result.seidel->sigma_stddev_per_mm2)
                                            : std::string()));
  lines.push_back(fmt::format("  distortion: up to {:.2f} um ({:.1f} px) over the spot field", field.max_um, field.max_px));
  // A corrected number with the U (k = 2) the calibration's covariance gives it (GUM's rounding), or alone.
  const auto with_u = [](const std::optional<ClinicalUncertainty>& u, const char* q, double value, int decimals) {
    const double expanded = u && u->quantities.count(q) ? u->quantities.at(q).expanded_k2 : 0.0;
    return FormatWithUncertainty(value, expanded, decimals);
  };
  if (sphere) {
    const auto& s = *sphere;
    lines.push_back(fmt::format(
        "  reference sphere R {} mm: radius error {:+.4f} -> {} mm, central power error {:+.3f} -> {} D{}",
        s.radius_true_mm, s.RadiusErrorMm(s.uncorrected), with_u(s.uncertainty, "radius_mm", s.RadiusErrorMm(s.corrected), 4),
        s.PowerErrorD(s.uncorrected), with_u(s.uncertainty, "central_axial_power_D", s.PowerErrorD(s.corrected), 3),
        s.uncertainty ? " (U, k = 2: the calibration's covariance; the ball's certificate joins it in the QA report)"
                      : ""));
  }
  if (const auto& rep = unit.sphere_repeats) {
    lines.push_back(fmt::format("  repeatability over {} images of the sphere: radius sd {:.2g} mm, central power sd "
                                "{:.2g} D (the QA report's budget uses them)",
                                rep->radius_mm.size(), util::SampleStddev(rep->radius_mm),
                                util::SampleStddev(rep->central_axial_power_D)));
  }
  lines.push_back(fmt::format("  paper cornea (simulated, informative): kx {:.4f} -> {}, ky {:.4f} -> {} (truth {}, {}{})",
                              paper.uncorrected.numbers.kx, with_u(paper.uncertainty, "kx", paper.corrected.numbers.kx, 4),
                              paper.uncorrected.numbers.ky, with_u(paper.uncertainty, "ky", paper.corrected.numbers.ky, 4),
                              paper.truth.kx, paper.truth.ky, paper.uncertainty ? "; U, k = 2" : ""));
  if (device) {
    const auto& f = device->calibration.fit;
    lines.push_back(fmt::format("  device from {} balls: {} (parameters +- U, k = 2)", device->calibration.detections.size(),
                                f.message));
    for (const char* name : {"rx_deg", "ry_deg", "principal_point_u_px", "principal_point_v_px", "a_mm"}) {
      if (const auto p = f.Parameter(name)) {
        lines.push_back(fmt::format("    {:<22} {}", p->name, FormatWithUncertainty(p->value, 2.0 * p->stddev, 6)));
      }
    }
    if (device->held_out) {
      const auto& h = *device->held_out;
      const auto err = [&](const pipeline::StageResult& st) { return st.numbers.radius_mm - h.radius_true_mm; };
      lines.push_back(fmt::format("  held-out ball R {} mm: radius error {:+.4f} (uncorrected), {:+.4f} (lens only), "
                                  "{:+.4f} mm (device)",
                                  h.radius_true_mm, err(h.stages.uncorrected), err(h.stages.lens_only),
                                  err(h.stages.device)));
    }
    const auto& pc = device->paper;
    lines.push_back(fmt::format("  paper cornea through the unit: kx {:.4f} (uncorrected), {:.4f} (lens only), {:.4f} "
                                "(device); truth {}",
                                pc.uncorrected.numbers.kx, pc.lens_only.numbers.kx, pc.device.numbers.kx, paper.truth.kx));
  }
  lines.push_back(fmt::format("  -> {}", r.out));
  return lines;
}

bool IsValidSerial(const std::string& serial) {
  if (serial.empty() || serial.size() > kMaxSerialLength || serial.front() == '.') return false;
  return std::all_of(serial.begin(), serial.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == '-';
  });
}

UnitResult CalibrateUnit(const UnitRequest& r, const std::function<void(const std::string&)>& log) {
  LoadedInputs in = LoadInputs(r);  // everything read and checked before any work or output, the images undecoded
  // OpenCV's image codecs (~0.15 s of CPU in dynamic linking) are loaded, in the background while the other images
  // are decoded, only when an image needs them: the PNGs a line writes are decoded without them (png_decode.h).
  std::future<void> codecs;
  if (NeedsCodecs(in)) codecs = imageio::LoadCodecsInBackground();
  UnitResult u;
  u.request = r;
  auto sphere_image = StartSphere(r, in);
  const auto rethrow_sphere = [&](const std::exception_ptr& error) { RethrowForImage(error, r.reference_sphere, r.serial); };
  try {
    u.calibration = CalibrateViews(r, in, log);
  } catch (...) {
    if (sphere_image.valid()) sphere_image.get();  // a sphere that cannot be read is the error to report
    throw;
  }
  u.created_utc = util::FileDateUtc();
  const auto& c = u.calibration;

  // The checks use the calibration as the record stores it: the exact model and its full covariance.
  UnitCalibration unit;
  unit.camera = c.result.camera;
  unit.covariance.names = calib::CameraParameterNames(c.result.model);
  unit.covariance.matrix = c.result.covariance;
  unit.covariance.full = true;
  u.check = CheckOptions{r.uncertainty, r.seed, r.jobs};
  // The two checks are independent: with more than one thread allowed, the paper cornea's runs beside the sphere's,
  // so that each one's serial parts (detection, nominal analyses, the draws' last stragglers) overlap the other's
  // draws. It starts as soon as the camera is calibrated, before the sphere is decoded and detected (the
  // 17 MB 16-bit sphere takes longer than the target's calibration, and the core that calibrated would wait). It
  // reads only the calibration, the camera and the configuration, which the sphere's thread does not write. Each
  // check writes only its own result: the record is the same either way. (A sphere that cannot be read is still the
  // error reported; the paper check then runs to its end first, as the future's destructor waits for it.)
  std::future<SimulatedCornea> paper;
  if (r.jobs != 1 && sphere_image.valid()) {
    paper = std::async(std::launch::async,
                       [&] { return SimulateThroughCalibratedCamera(unit, in.camera, in.config, u.check); });
  }
  SphereImage sphere = sphere_image.valid() ? sphere_image.get() : SphereImage{};
  if (!sphere.image.empty()) {
    if (sphere.detection_error) rethrow_sphere(sphere.detection_error);
    try {
      u.sphere = VerifyOnReferenceSphere(std::move(*sphere.detected), r.sphere_radius_mm, unit, in.camera, in.config,
                                         u.check);
    } catch (...) {
      rethrow_sphere(std::current_exception());
    }
    if (!r.sphere_repeats.empty()) u.sphere_repeats = MeasureSphereRepeats(r, in, unit, *u.sphere);
  }
  u.paper = paper.valid() ? paper.get() : SimulateThroughCalibratedCamera(unit, in.camera, in.config, u.check);
  u.field = MeasureDistortionField(c.result.camera, in, r.serial);
  if (!in.balls.empty()) {
    const auto lens = DetectionPlaneModelOf(c.result.camera, in.camera);
    if (!lens.ok) {
      throw std::runtime_error(
          fmt::format("{}: the calibration cannot be put on the detection plane: {}", r.serial, lens.message));
    }
    u.device = CalibrateDeviceStage(r, in, c, sphere.image, lens);
  }
  u.config = std::move(in.config);
  u.camera = std::move(in.camera);
  u.inputs = std::move(in.provenance);
  return u;
}

}  // namespace topocal::pipeline

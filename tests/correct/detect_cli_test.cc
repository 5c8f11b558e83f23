// topocal detect: the detected, indexed and flagged spots of a raw image, end to end through files;
// the orientation key refusing an undeclared mirror; reconstruct --image with the same estimator option.
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "model/null_screen_layout.h"
#include "synthetic.h"
#include "tests/cli_harness.h"
#include "tests/device_file.h"

namespace topocal::correct {
namespace {

namespace fs = std::filesystem;
using topocal::testing_cli::RunTopocal;

constexpr double kMatchPx = 1.0;  // far above the centre error, far below the spot spacing

class DetectCli : public topocal::testing_cli::TempDirTest {
 protected:
  void SetUp() override {
    TempDirTest::SetUp();
    auto cam = testing::DefaultCamera();
    cam.width_px = 1000;
    cam.height_px = 1000;
    cam.principal_point_px = {499.5, 499.5};
    Write("identity.json", testing_cli::NominalDeviceText(cam));
    cam.orientation = model::ImageOrientation::kFlipV;
    Write("flip_v.json", testing_cli::NominalDeviceText(cam));
    auto cfg = testing::PaperConfig();
    cfg.ideal_image.orientation_key = true;
    Write("keyed.json", model::ConfigToJson(cfg));
  }
};

struct Row {
  double u, v;
  std::string flags;
};

// ring,index -> row of a CSV with header `header` (u, v in columns 4 and 5 of the detect file, 2 and 3 of truth).
std::map<std::pair<int, int>, Row> ReadRows(const std::string& path, std::vector<Row>* ring0, int u_col) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::map<std::pair<int, int>, Row> out;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    if (f.size() < 6) continue;
    Row r{std::stod(f[u_col]), std::stod(f[u_col + 1]), f.size() > 6 ? f[6] : ""};
    const int ring = std::stoi(f[0]);
    if (ring == 0) {
      if (ring0) ring0->push_back(r);
    } else {
      out[{ring, std::stoi(f[1])}] = r;
    }
  }
  return out;
}

// Acceptance: 100 % indexing with 5 % missing spots and 6 glints, no glint accepted; a mirrored image
// measured when declared, refused when not (keyed screen).
TEST_F(DetectCli, IndexesEverySpotAcceptsNoGlintAndRefusesAnUndeclaredMirror) {
  const auto render = RunTopocal("render-spots --config " + Path("keyed.json") + " --device " + Path("flip_v.json") +
                                 " --spot psf --psf-px 2 --bits 8 --background 4 --peak 160 --noise 1 --gain 1" +
                                 " --drop 0.05 --glints 6 --seed 3 --out " + Path("img.png") + " --truth " +
                                 Path("truth.csv"));
  ASSERT_EQ(render.exit_code, 0) << render.output;
  const auto r = RunTopocal("detect --image " + Path("img.png") + " --device " + Path("flip_v.json") + " --config " +
                            Path("keyed.json") + " --out " + Path("spots.csv") + " --json " + Path("spots.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("orientation: confirmed"), std::string::npos) << r.output;
  std::vector<Row> glints_truth, unassigned;
  const auto truth = ReadRows(Path("truth.csv"), &glints_truth, 2);
  const auto found = ReadRows(Path("spots.csv"), &unassigned, 4);
  ASSERT_EQ(glints_truth.size(), 6u);
  EXPECT_EQ(found.size(), truth.size());  // every real spot identified (100 %)
  for (const auto& [id, t] : truth) {
    const auto it = found.find(id);
    ASSERT_NE(it, found.end()) << id.first << "," << id.second;
    EXPECT_LT(std::hypot(it->second.u - t.u, it->second.v - t.v), kMatchPx) << id.first << "," << id.second;
  }
  for (const auto& [id, f] : found) EXPECT_TRUE(truth.count(id)) << "identity given to a glint: " << id.first;
  EXPECT_EQ(unassigned.size(), 6u);  // every glint left without identity
  const auto j = nlohmann::json::parse(std::ifstream(Path("spots.json")));
  const auto cfg = testing::PaperConfig();
  EXPECT_EQ(j["missing"].size(), static_cast<size_t>(cfg.ideal_image.SpotCount()) - truth.size());
  EXPECT_EQ(j["estimator"], "psf");

  // The same image with the camera file that does not declare the mirror: refused, no output.
  const auto wrong = RunTopocal("detect --image " + Path("img.png") + " --device " + Path("identity.json") +
                                " --config " + Path("keyed.json") + " --out " + Path("wrong.csv"));
  EXPECT_EQ(wrong.exit_code, 2) << wrong.output;
  EXPECT_NE(wrong.output.find("orientation refused"), std::string::npos) << wrong.output;
  EXPECT_NE(wrong.output.find("flip_v"), std::string::npos) << wrong.output;
  EXPECT_FALSE(fs::exists(Path("wrong.csv")));

  // reconstruct --image takes the estimator and states the orientation.
  const auto rec = RunTopocal("reconstruct --config " + Path("keyed.json") + " --image " + Path("img.png") +
                              " --device " + Path("flip_v.json") + " --estimator centroid");
  EXPECT_EQ(rec.exit_code, 0) << rec.output;
  EXPECT_NE(rec.output.find("orientation: confirmed"), std::string::npos) << rec.output;
  const auto rec_wrong = RunTopocal("reconstruct --config " + Path("keyed.json") + " --image " + Path("img.png") +
                                    " --device " + Path("identity.json"));
  EXPECT_EQ(rec_wrong.exit_code, 2) << rec_wrong.output;
  EXPECT_NE(rec_wrong.output.find("orientation refused"), std::string::npos) << rec_wrong.output;
}

TEST_F(DetectCli, AnUnkeyedScreenSaysTheRiskAndBadInputIsOneLine) {
  const std::string paper = std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json";
  ASSERT_EQ(RunTopocal("render-spots --config " + paper + " --device " + Path("identity.json") + " --out " +
                       Path("img.png")).exit_code, 0);
  const auto r = RunTopocal("detect --image " + Path("img.png") + " --device " + Path("identity.json") + " --config " +
                            paper + " --out " + Path("spots.csv") + " --estimator centroid");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("orientation: NOT verifiable"), std::string::npos) << r.output;
  const auto bad = RunTopocal("detect --image " + Path("missing.png") + " --device " + Path("identity.json") +
                              " --config " + paper + " --out " + Path("x.csv"));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("missing.png"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(Path("x.csv")));
  const auto est = RunTopocal("detect --image " + Path("img.png") + " --device " + Path("identity.json") +
                              " --config " + paper + " --out " + Path("x.csv") + " --estimator median");
  EXPECT_NE(est.exit_code, 0);
  EXPECT_FALSE(fs::exists(Path("x.csv")));
}

// detect checks every identity against the surface the others give, as reconstruct --image does (one library
// call): on a clinical capture (an upper lid with its skin, lash shadows, an iris, defocus growing to the rim, motion
// blur, tear film, glints) the spots the surface rejects are flagged surface_outlier and left out, the counts are
// reconstruct's, and every identity written is right (its own spot the nearest).
TEST_F(DetectCli, EveryIdentityIsCheckedAgainstTheSurfaceAsReconstructChecksIt) {
  const std::string paper = std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json";
  const auto render = RunTopocal(
      "render-spots --config " + paper + " --device " + Path("identity.json") +
      " --sigma 0 --upper-lid 0.2 --lid-skin 8000 --lashes 4 --iris 2500 --psf-px 1.5 --defocus-rim-px 3 "
      "--motion-blur-px 1.5 --motion-blur-deg 30 --tear-film 2 --glints 2 --seed 5 --out " + Path("clinical.png") +
      " --truth " + Path("truth.csv"));
  ASSERT_EQ(render.exit_code, 0) << render.output;
  const auto det = RunTopocal("detect --image " + Path("clinical.png") + " --device " + Path("identity.json") +
                              " --config " + paper + " --out " + Path("spots.csv") + " --json " + Path("spots.json"));
  ASSERT_EQ(det.exit_code, 0) << det.output;
  const auto rec = RunTopocal("reconstruct --image " + Path("clinical.png") + " --device " + Path("identity.json") +
                              " --config " + paper + " --json " + Path("cornea.json"));
  ASSERT_EQ(rec.exit_code, 0) << rec.output;
  const auto dj = nlohmann::json::parse(std::ifstream(Path("spots.json")));
  const auto rj = nlohmann::json::parse(std::ifstream(Path("cornea.json")));
  EXPECT_TRUE(dj["valid"].get<bool>());
  EXPECT_EQ(dj["capture"], rj["capture"]);  // the same identities, rejections and counts
  EXPECT_GE(dj["capture"]["surface_outliers"].get<int>(), 1);

  const auto truth = ReadRows(Path("truth.csv"), nullptr, 2);
  std::vector<Row> blobs;
  const auto found = ReadRows(Path("spots.csv"), &blobs, 4);
  int rejected = 0, usable = 0;
  // A rejected spot whose identity the surface does not hold either is written as a blob, its flags kept.
  for (const auto& b : blobs) rejected += b.flags.find("surface_outlier") != std::string::npos;
  for (const auto& [id, f] : found) {
    const auto t = truth.find(id);
    ASSERT_NE(t, truth.end()) << "identity given to a blob that is no spot: " << id.first << "," << id.second;
    // Right: its own spot is the nearest (a centre a lash pulled by a few px is still nearest to its own spot,
    // ~20 px from the next).
    const double own = std::hypot(f.u - t->second.u, f.v - t->second.v);
    for (const auto& [other, o] : truth) {
      if (other != id) EXPECT_GT(std::hypot(f.u - o.u, f.v - o.v), own) << id.first << "," << id.second;
    }
    rejected += f.flags.find("surface_outlier") != std::string::npos;
    bool excluded = false;
    for (const char* flag : {"near_blob", "truncated", "flux_outlier", "uneven_background", "surface_outlier"}) {
      excluded = excluded || f.flags.find(flag) != std::string::npos;
    }
    usable += !excluded;
  }
  EXPECT_EQ(rejected, dj["capture"]["surface_outliers"].get<int>());
  EXPECT_EQ(usable, dj["capture"]["usable"].get<int>());
}

// A capture the data cannot support (a lid over 45 % of the pattern hides the sim-K zone above the centre): detect
// exits 4 as reconstruct does, writes no spots file, and its JSON is marked invalid with the reason.
TEST_F(DetectCli, IdentitiesTheDataCannotSupportAreRefusedWithoutASpotsFile) {
  const std::string paper = std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json";
  ASSERT_EQ(RunTopocal("render-spots --config " + paper + " --device " + Path("identity.json") +
                       " --upper-lid 0.45 --out " + Path("lid45.png")).exit_code, 0);
  const auto det = RunTopocal("detect --image " + Path("lid45.png") + " --device " + Path("identity.json") +
                              " --config " + paper + " --out " + Path("spots.csv") + " --json " + Path("spots.json"));
  EXPECT_EQ(det.exit_code, 4) << det.output;
  EXPECT_NE(det.output.find("REFUSED"), std::string::npos) << det.output;
  EXPECT_NE(det.output.find("topocal: " + Path("lid45.png")), std::string::npos) << det.output;
  EXPECT_FALSE(fs::exists(Path("spots.csv")));
  const auto j = nlohmann::json::parse(std::ifstream(Path("spots.json")));
  EXPECT_FALSE(j["valid"].get<bool>());
  ASSERT_FALSE(j["refused"].empty());
  const auto rec = RunTopocal("reconstruct --image " + Path("lid45.png") + " --device " + Path("identity.json") +
                              " --config " + paper);
  EXPECT_EQ(rec.exit_code, 4) << rec.output;
}

}  // namespace
}  // namespace topocal::correct

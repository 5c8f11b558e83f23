#include "model/config.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace topocal::model {
namespace {

const char* kPaper = R"({
  "ideal_image": {"rho0_mm": 0.031, "rhoN_mm": 0.35, "rings_N": 11, "eta0": 8, "eta": 8},
  "topographer": {"a_mm": 5.2, "b_mm": 70.0, "re_mm": 7.8, "cone_semi_angle_deg": 10.79, "cone_vertex_z_mm": -85.5},
  "cornea": {"rx_mm": 8.35, "ry_mm": 7.63, "kx": -0.43, "ky": -0.25, "alpha_deg": 17.0},
  "distortion": {"model": "seidel", "MT": -0.065, "sigmas_per_mm2": [-2.0e-4, 0.0, 2.0e-4]}
})";

std::string ErrorOf(const std::string& text) {
  try {
    ParseConfig(text, "cfg.json");
  } catch (const util::ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string Mutated(const std::function<void(nlohmann::json&)>& f) {
  auto j = nlohmann::json::parse(kPaper);
  f(j);
  return j.dump();
}

TEST(Config, PaperFileLoads) {
  const Config c = LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  EXPECT_EQ(c.ideal_image.rings_N, 11);
  EXPECT_DOUBLE_EQ(c.topographer.cone_vertex_z_mm, -85.5);
  EXPECT_DOUBLE_EQ(c.cornea.alpha_deg, 17.0);
  EXPECT_EQ(c.distortion.sigmas_per_mm2.size(), 7u);
  EXPECT_EQ(c.reconstruction.method, "iterative");
}

TEST(Config, RoundTripsThroughJson) {
  const Config c = ParseConfig(kPaper, "cfg.json");
  const Config d = ParseConfig(ConfigToJson(c), "again.json");
  EXPECT_EQ(d.distortion.sigmas_per_mm2, c.distortion.sigmas_per_mm2);
  EXPECT_EQ(d.cornea.rx_mm, c.cornea.rx_mm);
}

struct Case {
  std::function<void(nlohmann::json&)> mutate;
  std::string message;
};

TEST(Config, EachErrorNamesFileKeyAndProblem) {
  const std::vector<Case> cases = {
      {[](auto& j) { j["cornea"]["rz_mm"] = 1.0; }, "cfg.json: cornea.rz_mm: unknown key"},
      {[](auto& j) { j["extra"] = 1; }, "cfg.json: extra: unknown key"},
      {[](auto& j) { j["cornea"].erase("kx"); }, "cfg.json: cornea.kx: missing"},
      {[](auto& j) { j.erase("topographer"); }, "cfg.json: topographer: missing"},
      {[](auto& j) { j["topographer"]["a_mm"] = "5.2"; }, "cfg.json: topographer.a_mm: must be a number (got \"5.2\")"},
      {[](auto& j) { j["ideal_image"]["rings_N"] = 11.5; }, "cfg.json: ideal_image.rings_N: must be an integer (got 11.5)"},
      {[](auto& j) { j["cornea"]["rx_mm"] = -8.0; }, "cfg.json: cornea.rx_mm: must be > 0 (got -8)"},
      {[](auto& j) { j["topographer"]["b_mm"] = 0.0; }, "cfg.json: topographer.b_mm: must be > 0 (got 0)"},
      {[](auto& j) { j["ideal_image"]["rings_N"] = 0; }, "cfg.json: ideal_image.rings_N: must be >= 1 (got 0)"},
      {[](auto& j) { j["distortion"]["sigmas_per_mm2"] = nlohmann::json::array(); },
       "cfg.json: distortion.sigmas_per_mm2: must not be empty"},
      {[](auto& j) { j["distortion"]["sigmas_per_mm2"][1] = "x"; },
       "cfg.json: distortion.sigmas_per_mm2[1]: must be a finite number (got \"x\")"},
      {[](auto& j) { j["distortion"]["model"] = "fisheye"; }, "cfg.json: distortion.model: must be \"seidel\" (got \"fisheye\")"},
      {[](auto& j) { j["topographer"]["cone_vertex_z_mm"] = 85.5; },
       "cfg.json: topographer.cone_vertex_z_mm: must lie behind the pinhole, below -b_mm = -70 (got 85.5; see "
       "docs/paper-decisions.md)"},
      {[](auto& j) { j["topographer"]["cone_semi_angle_deg"] = 95; },
       "cfg.json: topographer.cone_semi_angle_deg: must lie in (0, 90) degrees (got 95)"},
      {[](auto& j) { j["reconstruction"] = {{"method", "magic"}}; },
       "cfg.json: reconstruction.method: must be \"iterative\" or \"paper\" (got \"magic\")"},
      {[](auto& j) { j["cornea"] = 3; }, "cfg.json: cornea: must be a JSON object"},
  };
  for (const auto& c : cases) EXPECT_EQ(ErrorOf(Mutated(c.mutate)), c.message);
}

TEST(Config, NotJsonAndMissingFile) {
  EXPECT_NE(ErrorOf("{ not json").find("cfg.json: not valid JSON (byte"), std::string::npos);
  // A number beyond double's range is nlohmann's out_of_range, not parse_error: still bad input naming the key.
  EXPECT_EQ(ErrorOf(R"({"ideal_image": {"rho0_mm": 1e999}})"),
            "cfg.json: ideal_image.rho0_mm: a number beyond the range of a double");
  try {
    LoadConfig("/nonexistent/x.json");
    FAIL();
  } catch (const util::ConfigError& e) {
    EXPECT_STREQ(e.what(), "/nonexistent/x.json: (file): cannot be opened for reading");
  }
}

}  // namespace
}  // namespace topocal::model

namespace topocal::model {
namespace {
TEST(Config, ConicUndefinedWhereRaysLand) {
  const std::string msg = ErrorOf(Mutated([](auto& j) { j["cornea"]["kx"] = 4.5; }));
  EXPECT_EQ(msg.rfind("cfg.json: cornea.kx: the biconic is undefined beyond rho = ", 0), 0u) << msg;
}
}  // namespace
}  // namespace topocal::model

// Limits and the decision rule: the bundled data/limits.json is the built-in default; a malformed limits file is
// refused naming the key; guarded acceptance adds U to |error|, simple acceptance does not.
#include "report/acceptance.h"

#include <gtest/gtest.h>

#include "model/io.h"
#include "tests/report/record_fixture.h"

namespace topocal::report {
namespace {

using testing::FreshDir;
using testing::MakeRecord;

std::string LimitsError(const std::string& text) {
  const std::string path = FreshDir("limits") + "/limits.json";
  model::WriteFileAtomic(path, text);
  try {
    LoadLimits(path);
  } catch (const model::InputError& e) {
    return e.what();
  }
  return "";
}

nlohmann::json BundledLimits() {
  return nlohmann::json::parse(model::ReadFile(std::string(TOPOCAL_SOURCE_DIR) + "/data/limits.json"));
}

TEST(Limits, BundledFileIsTheBuiltInDefault) {
  const Limits file = LoadLimits(std::string(TOPOCAL_SOURCE_DIR) + "/data/limits.json");
  const Limits def = DefaultLimits();
  EXPECT_EQ(file.rule, def.rule);
  for (const auto& [a, b] : {std::pair{&file.calibration_rms_px, &def.calibration_rms_px},
                             std::pair{&file.sphere_radius_error_mm, &def.sphere_radius_error_mm},
                             std::pair{&file.sphere_power_error_D, &def.sphere_power_error_D},
                             std::pair{&file.paper_radius_error_mm, &def.paper_radius_error_mm},
                             std::pair{&file.paper_conic_error, &def.paper_conic_error}}) {
    EXPECT_EQ(a->max, b->max);
    EXPECT_EQ(a->source, b->source);
  }
}

TEST(Limits, MalformedFilesAreRefusedNamingTheKey) {
  auto j = BundledLimits();
  j["limits"]["sphere_power_error_D"]["max"] = -0.25;
  EXPECT_NE(LimitsError(j.dump()).find("limits.json: limits.sphere_power_error_D.max: must be a finite number > 0"),
            std::string::npos);
  j = BundledLimits();
  j["limits"].erase("paper_conic_error");
  EXPECT_NE(LimitsError(j.dump()).find("limits.json: limits.paper_conic_error: missing"), std::string::npos);
  j = BundledLimits();
  j["limits"]["typo_limit"] = {{"max", 1}, {"source", "x"}};
  EXPECT_NE(LimitsError(j.dump()).find("limits.json: limits.typo_limit: unknown key"), std::string::npos);
  j = BundledLimits();
  j["decision_rule"] = "optimistic";
  EXPECT_NE(LimitsError(j.dump()).find("limits.json: decision_rule: must be \"guarded\" or \"simple\""),
            std::string::npos);
  j = BundledLimits();
  j["limits"]["calibration_rms_px"]["source"] = "";
  EXPECT_NE(LimitsError(j.dump()).find("limits.calibration_rms_px.source"), std::string::npos);
  EXPECT_NE(LimitsError("{not json").find("limits.json: not valid JSON"), std::string::npos);
  EXPECT_NE(LimitsError("{}").find("limits.json: decision_rule: missing"), std::string::npos);
}

TEST(Acceptance, TheFixturePassesTheDefaults) {
  const auto f = MakeRecord(FreshDir("pass"));
  const Verdict v = Evaluate(ReadUnitRecord(f.dir), DefaultLimits());
  EXPECT_TRUE(v.pass);
  EXPECT_EQ(v.checks.size(), 7u);  // rms, sphere radius, sphere power, paper r_x, r_y, k_x, k_y
  for (const Check& c : v.checks) EXPECT_TRUE(c.pass) << c.what << ": " << c.note;
}

TEST(Acceptance, GuardedAddsUAndSimpleDoesNot) {
  // Paper k_x: |error| = 0.0002, U = 0.003. A limit between the two separates the rules.
  const auto f = MakeRecord(FreshDir("rules"));
  const UnitRecord rec = ReadUnitRecord(f.dir);
  Limits l = DefaultLimits();
  l.paper_conic_error.max = 0.002;
  auto conic = [&](const Verdict& v) {
    for (const Check& c : v.checks) {
      if (c.what.find("k_x") != std::string::npos) return c;
    }
    return Check{};
  };
  const Check guarded = conic(Evaluate(rec, l));
  EXPECT_NEAR(*guarded.error, 0.0002, 1e-12);
  EXPECT_DOUBLE_EQ(*guarded.U, 0.003);
  EXPECT_FALSE(guarded.pass);
  l.rule = DecisionRule::kSimple;
  EXPECT_TRUE(conic(Evaluate(rec, l)).pass);
  EXPECT_TRUE(Evaluate(rec, DefaultLimits()).pass);
}

TEST(Acceptance, SphereUncertaintyComesFromRxRyAndPowerFromRadius) {
  const auto f = MakeRecord(FreshDir("sphereu"));
  const Verdict v = Evaluate(ReadUnitRecord(f.dir), DefaultLimits());
  ASSERT_EQ(v.checks[1].id, "sphere_radius_error_mm");
  EXPECT_DOUBLE_EQ(*v.checks[1].U, 0.002);  // (U(r_x) + U(r_y)) / 2 with both 0.002
  ASSERT_EQ(v.checks[2].id, "sphere_power_error_D");
  const double r = 7.8005;
  EXPECT_NEAR(*v.checks[2].U, 1000 * 0.3375 * 0.002 / (r * r), 1e-12);
  // The record's own U of radius and central power (what `unit calibrate` writes) take precedence.
  auto g = MakeRecord(FreshDir("sphereu2"));
  g.unit["verification"]["uncertainty"]["quantities"]["radius_mm"] = {{"mean", 7.8005}, {"U", 0.0011}};
  g.unit["verification"]["uncertainty"]["quantities"]["central_axial_power_D"] = {{"mean", 43.27}, {"U", 0.007}};
  g.WriteUnitJson();
  const Verdict w = Evaluate(ReadUnitRecord(g.dir), DefaultLimits());
  EXPECT_DOUBLE_EQ(*w.checks[1].U, 0.0011);
  EXPECT_DOUBLE_EQ(*w.checks[2].U, 0.007);
}

TEST(Acceptance, WithoutVerificationOrUncertaintyTheGuardedRuleFails) {
  auto f = MakeRecord(FreshDir("nover"));
  f.unit.erase("verification");
  f.unit["paper_cornea"].erase("uncertainty");
  f.WriteUnitJson();
  const UnitRecord rec = ReadUnitRecord(f.dir);
  const Verdict v = Evaluate(rec, DefaultLimits());
  EXPECT_FALSE(v.pass);
  EXPECT_TRUE(v.checks[0].pass);  // the calibration RMS needs no U
  EXPECT_FALSE(v.checks[1].error.has_value());
  EXPECT_NE(v.checks[1].note.find("no reference-sphere verification"), std::string::npos);
  EXPECT_NE(v.checks[3].note.find("no U in the record"), std::string::npos);
  Limits simple = DefaultLimits();
  simple.rule = DecisionRule::kSimple;
  const Verdict vs = Evaluate(rec, simple);
  EXPECT_TRUE(vs.checks[3].pass);   // paper checks judged on |error| alone
  EXPECT_FALSE(vs.checks[1].pass);  // still not verified
}

TEST(Acceptance, CalibrationRmsAboveTheLimitFails) {
  const auto f = MakeRecord(FreshDir("rms"));
  Limits l = DefaultLimits();
  l.calibration_rms_px.max = 1e-4;
  const Verdict v = Evaluate(ReadUnitRecord(f.dir), l);
  EXPECT_FALSE(v.checks[0].pass);
  EXPECT_FALSE(v.pass);
}

}  // namespace
}  // namespace topocal::report

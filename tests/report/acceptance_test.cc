// Limits and the decision rule: the bundled data/limits.json is the built-in default; a malformed limits file is
// refused naming the key; guarded acceptance adds U to |error|, simple acceptance does not.
#include "report/acceptance.h"

#include <gtest/gtest.h>

#include "tests/report/record_fixture.h"
#include "util/io.h"

namespace topocal::report {
namespace {

using testing::FreshDir;
using testing::MakeRecord;

// The record with hand-picked check numbers (tests/report/record_fixture.h): the rule, the budget and the page are
// functions of the numbers, checked here against hand computations.
testing::RecordFixture MakeHandRecord(const std::string& dir) {
  testing::RecordFixture f = MakeRecord(dir);
  testing::UseHandPickedChecks(f);
  return f;
}

std::string LimitsError(const std::string& text) {
  const std::string path = FreshDir("limits") + "/limits.json";
  util::WriteFileAtomic(path, text);
  try {
    LoadLimits(path);
  } catch (const util::InputError& e) {
    return e.what();
  }
  return "";
}

nlohmann::json BundledLimits() {
  return nlohmann::json::parse(util::ReadFile(std::string(TOPOCAL_SOURCE_DIR) + "/data/limits.json"));
}

TEST(Limits, BundledFileIsTheBuiltInDefault) {
  const Limits file = LoadLimits(std::string(TOPOCAL_SOURCE_DIR) + "/data/limits.json");
  const Limits def = DefaultLimits();
  EXPECT_EQ(file.rule, def.rule);
  for (const auto& [a, b] : {std::pair{&file.calibration_rms_px, &def.calibration_rms_px},
                             std::pair{&file.sphere_radius_error_mm, &def.sphere_radius_error_mm},
                             std::pair{&file.sphere_power_error_D, &def.sphere_power_error_D},
                             std::pair{&file.paper_radius_error_mm, &def.paper_radius_error_mm},
                             std::pair{&file.paper_conic_error, &def.paper_conic_error},
                             std::pair{&file.device_chi2_per_dof, &def.device_chi2_per_dof}}) {
    EXPECT_EQ(a->max, b->max);
    EXPECT_EQ(a->source, b->source);
  }
}

// device_chi2_per_dof came after the first limits files: a file without it judges device records by the default.
TEST(Limits, AFileWithoutTheDeviceLimitTakesItsDefault) {
  auto j = BundledLimits();
  j["limits"].erase("device_chi2_per_dof");
  const std::string path = ::testing::TempDir() + "/limits-no-device.json";
  util::WriteFileAtomic(path, j.dump());
  const Limits l = LoadLimits(path);
  EXPECT_EQ(l.device_chi2_per_dof.max, kDefaultDeviceChi2PerDof);
  EXPECT_EQ(l.device_chi2_per_dof.source, DefaultLimits().device_chi2_per_dof.source);
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

// Hostile JSON: 1e999 was exit 1 with nlohmann's raw message; a format_version of 2^32 + 1 read as 1.
TEST(Limits, HostileJsonIsBadInputNamingTheKey) {
  std::string text = BundledLimits().dump();
  const std::string max = "\"max\":";
  const auto at = text.find(max, text.find("\"calibration_rms_px\""));
  ASSERT_NE(at, std::string::npos);
  const std::string huge = text.substr(0, at + max.size()) + "1e999" + text.substr(text.find_first_of(",}", at));
  EXPECT_NE(LimitsError(huge).find("limits.json: limits.calibration_rms_px.max: a number beyond the range of a double"),
            std::string::npos) << LimitsError(huge);
  auto j = BundledLimits();
  j["format_version"] = 4294967297ULL;
  EXPECT_NE(LimitsError(j.dump()).find("limits.json: format_version: must be 1"), std::string::npos);
  const std::string dup = "{\"format\": \"x\", \"format\": \"y\"}";
  EXPECT_NE(LimitsError(dup).find("limits.json: format: given twice in one object"), std::string::npos);
  EXPECT_NE(LimitsError(std::string(100000, '[')).find("limits.json: nested deeper than"), std::string::npos);
}

TEST(Acceptance, TheFixturePassesTheDefaults) {
  const auto f = MakeHandRecord(FreshDir("pass"));
  const Verdict v = Evaluate(ReadUnitRecord(f.dir), DefaultLimits());
  EXPECT_TRUE(v.pass);
  EXPECT_EQ(v.checks.size(), 3u);  // rms, sphere radius, sphere power: evidence the fit did not use
  for (const Check& c : v.checks) EXPECT_TRUE(c.pass) << c.what << ": " << c.note;
  // The paper cornea: four informative rows, never checks, whatever their thresholds say.
  const auto rows = PaperCorneaRows(ReadUnitRecord(f.dir), DefaultLimits());
  ASSERT_EQ(rows.size(), 4u);
  for (const Check& c : rows) EXPECT_TRUE(c.pass) << c.what;
  Limits strict = DefaultLimits();
  strict.paper_conic_error.max = 1e-6;
  EXPECT_FALSE(PaperCorneaRows(ReadUnitRecord(f.dir), strict)[2].pass);
  EXPECT_TRUE(Evaluate(ReadUnitRecord(f.dir), strict).pass);
}

TEST(Acceptance, GuardedAddsUAndSimpleDoesNot) {
  // The sphere's radius: |error| = 0.0005 mm and a U of several micrometres. A limit between the error and the
  // error + U separates the rules.
  const auto f = MakeHandRecord(FreshDir("rules"));
  const UnitRecord rec = ReadUnitRecord(f.dir);
  Limits l = DefaultLimits();
  const auto radius = [&](const Verdict& v) {
    for (const Check& c : v.checks) {
      if (c.id == "sphere_radius_error_mm") return c;
    }
    return Check{};
  };
  const Check at_default = radius(Evaluate(rec, l));
  ASSERT_TRUE(at_default.error && at_default.U);
  EXPECT_NEAR(*at_default.error, 0.0005, 1e-9);
  l.sphere_radius_error_mm.max = *at_default.error + 0.5 * *at_default.U;
  const Check guarded = radius(Evaluate(rec, l));
  EXPECT_FALSE(guarded.pass);
  l.rule = DecisionRule::kSimple;
  EXPECT_TRUE(radius(Evaluate(rec, l)).pass);
  EXPECT_TRUE(Evaluate(rec, DefaultLimits()).pass);
}

TEST(Acceptance, SphereCalibrationTermComesFromRxRyAndPowerFromRadius) {
  const auto f = MakeHandRecord(FreshDir("sphereu"));
  const Verdict v = Evaluate(ReadUnitRecord(f.dir), DefaultLimits());
  ASSERT_EQ(v.checks[1].id, "sphere_radius_error_mm");
  ASSERT_EQ(v.checks[1].budget.size(), 3u);
  EXPECT_DOUBLE_EQ(v.checks[1].budget[0].u, 0.001);  // (U(r_x) + U(r_y)) / 2 with both 0.002, halved to k = 1
  ASSERT_EQ(v.checks[2].id, "sphere_power_error_D");
  const double r = 7.8005;
  EXPECT_NEAR(v.checks[2].budget[0].u, 0.5 * 1000 * 0.3375 * 0.002 / (r * r), 1e-12);
  // The record's own U of radius and central power (what `unit calibrate` writes) take precedence.
  auto g = MakeHandRecord(FreshDir("sphereu2"));
  g.unit["verification"]["uncertainty"]["quantities"]["radius_mm"] = {{"mean", 7.8005}, {"U", 0.0011}};
  g.unit["verification"]["uncertainty"]["quantities"]["central_axial_power_D"] = {{"mean", 43.27}, {"U", 0.007}};
  g.WriteUnitJson();
  const Verdict w = Evaluate(ReadUnitRecord(g.dir), DefaultLimits());
  EXPECT_DOUBLE_EQ(w.checks[1].budget[0].u, 0.00055);
  EXPECT_DOUBLE_EQ(w.checks[2].budget[0].u, 0.0035);
}

// The budget's combination against a hand computation (GUM Eq. 10, independent inputs, k = 2).
TEST(Acceptance, UncertaintyBudgetCombinesCalibrationRepeatabilityAndCertificate) {
  auto g = MakeHandRecord(FreshDir("budget"));
  auto& ver = g.unit["verification"];
  ver["uncertainty"]["quantities"]["radius_mm"] = {{"mean", 7.8005}, {"U", 0.0011}};
  ver["uncertainty"]["quantities"]["central_axial_power_D"] = {{"mean", 43.27}, {"U", 0.007}};
  // Three repeated images: radii 7.801, 7.803, 7.802 mm (s = 0.001 mm), powers 43.25, 43.27, 43.26 D (s = 0.01 D).
  ver["repeatability"] = {{"radius_mm", {7.801, 7.803, 7.802}}, {"central_axial_power_D", {43.25, 43.27, 43.26}}};
  g.WriteUnitJson();
  BudgetOptions budget;
  budget.ball_radius_U_mm = 0.004;  // certificate: U = 4 um (k = 2), u = 2 um
  const Verdict v = Evaluate(ReadUnitRecord(g.dir), DefaultLimits(), budget);
  const Check& radius = v.checks[1];
  ASSERT_EQ(radius.budget.size(), 3u);
  EXPECT_DOUBLE_EQ(radius.budget[0].u, 0.00055);                   // calibration: 0.0011 / 2
  EXPECT_NEAR(radius.budget[1].u, 0.001, 1e-12);                   // repeatability: s of the three radii
  EXPECT_DOUBLE_EQ(radius.budget[2].u, 0.002);                     // certificate: 0.004 / 2
  // U = 2 sqrt(0.00055^2 + 0.001^2 + 0.002^2) = 2 sqrt(5.3025e-6) = 0.0046054316 mm
  EXPECT_NEAR(*radius.U, 0.0046054316, 1e-10);
  const Check& power = v.checks[2];
  ASSERT_EQ(power.budget.size(), 3u);
  EXPECT_DOUBLE_EQ(power.budget[0].u, 0.0035);                     // calibration: 0.007 / 2
  EXPECT_NEAR(power.budget[1].u, 0.01, 1e-12);                     // repeatability: s of the three powers
  // certificate through dP/dR = 1000 (1.3375 - 1) / 7.8^2 = 5.5473373 D/mm: 0.002 mm -> 0.0110947 D
  EXPECT_NEAR(power.budget[2].u, 0.0110946746, 1e-9);
  // U = 2 sqrt(0.0035^2 + 0.01^2 + 0.0110947^2) = 0.0306817 D
  EXPECT_NEAR(*power.U, 0.0306817081, 1e-9);
  EXPECT_NE(radius.budget[1].source.find("3 repeated images"), std::string::npos);
  EXPECT_NE(radius.budget[2].source.find("certificate: U = 0.004 mm"), std::string::npos);

  // Without repeats and certificate: the documented defaults, u_rep = 5 um, u_cert = 1 um / 2.
  const auto f = MakeHandRecord(FreshDir("budgetdefault"));
  const Verdict d = Evaluate(ReadUnitRecord(f.dir), DefaultLimits());
  EXPECT_DOUBLE_EQ(d.checks[1].budget[1].u, kDefaultRepeatabilityRadiusMm);
  EXPECT_DOUBLE_EQ(d.checks[1].budget[2].u, 0.5 * kDefaultBallRadiusUMm);
  // U = 2 sqrt(0.001^2 + 0.005^2 + 0.0005^2) = 0.0102469508 mm
  EXPECT_NEAR(*d.checks[1].U, 0.0102469508, 1e-10);
  EXPECT_NE(d.checks[1].budget[2].source.find("no certificate value given"), std::string::npos);

  // The certificate's U is the user's number: a bad one is refused.
  BudgetOptions bad;
  bad.ball_radius_U_mm = -1;
  EXPECT_THROW(Evaluate(ReadUnitRecord(f.dir), DefaultLimits(), bad), util::InputError);
}

TEST(Acceptance, AGuardBandThatTheBudgetWidensTurnsAPassIntoAFail) {
  // Radius error 0.0005 mm; with the default budget U = 0.0102 mm: a 0.01 mm limit passes by simple acceptance and
  // fails by guarded acceptance; the calibration's U alone (0.002 mm) would have passed it.
  const auto f = MakeHandRecord(FreshDir("guard"));
  const UnitRecord rec = ReadUnitRecord(f.dir);
  Limits l = DefaultLimits();
  l.sphere_radius_error_mm.max = 0.01;
  EXPECT_FALSE(Evaluate(rec, l).checks[1].pass);
  l.rule = DecisionRule::kSimple;
  EXPECT_TRUE(Evaluate(rec, l).checks[1].pass);
}

TEST(Acceptance, MalformedRepeatabilityIsRefused) {
  auto f = MakeHandRecord(FreshDir("badrep"));
  f.unit["verification"]["repeatability"] = {{"radius_mm", {7.8}}, {"central_axial_power_D", {43.2}}};
  f.WriteUnitJson();
  try {
    ReadUnitRecord(f.dir);
    FAIL() << "a single repeat was accepted";
  } catch (const util::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("verification.repeatability.radius_mm: needs at least 2"), std::string::npos)
        << e.what();
  }
}

TEST(Acceptance, WithoutVerificationOrUncertaintyTheGuardedRuleFails) {
  auto f = MakeHandRecord(FreshDir("nover"));
  f.unit.erase("verification");
  f.unit["paper_cornea"].erase("uncertainty");
  f.WriteUnitJson();
  const UnitRecord rec = ReadUnitRecord(f.dir);
  const Verdict v = Evaluate(rec, DefaultLimits());
  EXPECT_FALSE(v.pass);
  EXPECT_TRUE(v.checks[0].pass);  // the calibration RMS needs no U
  EXPECT_FALSE(v.checks[1].error.has_value());
  EXPECT_NE(v.checks[1].note.find("no reference-sphere verification"), std::string::npos);
  ASSERT_EQ(v.checks.size(), 3u);
  // The paper cornea's rows without U: the guarded rule cannot decide them, the simple one judges |error| alone.
  EXPECT_NE(PaperCorneaRows(rec, DefaultLimits())[0].note.find("no U in the record"), std::string::npos);
  Limits simple = DefaultLimits();
  simple.rule = DecisionRule::kSimple;
  const Verdict vs = Evaluate(rec, simple);
  EXPECT_TRUE(PaperCorneaRows(rec, simple)[0].pass);
  EXPECT_FALSE(vs.checks[1].pass);  // still not verified
}

TEST(Acceptance, CalibrationRmsAboveTheLimitFails) {
  const auto f = MakeHandRecord(FreshDir("rms"));
  Limits l = DefaultLimits();
  l.calibration_rms_px.max = 1e-4;
  const Verdict v = Evaluate(ReadUnitRecord(f.dir), l);
  EXPECT_FALSE(v.checks[0].pass);
  EXPECT_FALSE(v.pass);
}

}  // namespace
}  // namespace topocal::report

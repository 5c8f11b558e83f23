// The one strict JSON reader (util/json_section.h) on the inputs that crashed or fooled topocal's earlier readers:
// nesting deep enough to overflow the parser's stack, numbers beyond double's range, integers beyond int's range
// (they wrapped around silently), keys given twice, and megabyte-long values echoed whole in an error line.
#include <gtest/gtest.h>

#include <string>

#include "model/config.h"
#include "util/json_section.h"

namespace topocal::model {
namespace {

// The paper's configuration (data/paper.json without the reconstruction block), as text to be edited by hand: the
// hostile inputs below cannot be built with nlohmann (it refuses 1e999 and duplicate keys itself).
const std::string kPaper = R"({
  "ideal_image": {"rho0_mm": 0.031, "rhoN_mm": 0.35, "rings_N": 11, "eta0": 8, "eta": 8},
  "topographer": {"a_mm": 5.2, "b_mm": 70.0, "re_mm": 7.8, "cone_semi_angle_deg": 10.79, "cone_vertex_z_mm": -85.5},
  "cornea": {"rx_mm": 8.35, "ry_mm": 7.63, "kx": -0.43, "ky": -0.25, "alpha_deg": 17.0},
  "distortion": {"model": "seidel", "MT": -0.065, "sigmas_per_mm2": [-2.0e-4, 0.0, 2.0e-4]}
})";

std::string Replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

// The ConfigError message of parsing `text` as a configuration ("" when it parses).
std::string ConfigErrorOf(const std::string& text) {
  try {
    ParseConfig(text, "cfg.json");
  } catch (const util::ConfigError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << "one line";
    return what;
  }
  return "";
}

TEST(JsonStrict, ThePaperConfigurationParses) { EXPECT_EQ(ConfigErrorOf(kPaper), ""); }

TEST(JsonStrict, ANumberBeyondDoubleNamesTheFileAndKey) {
  const std::string e = ConfigErrorOf(Replaced(kPaper, "\"rhoN_mm\": 0.35", "\"rhoN_mm\": 1e999"));
  EXPECT_EQ(e, "cfg.json: ideal_image.rhoN_mm: a number beyond the range of a double");
  const std::string in_array = ConfigErrorOf(Replaced(kPaper, "0.0, 2.0e-4", "0.0, -1e999"));
  EXPECT_EQ(in_array, "cfg.json: distortion.sigmas_per_mm2[]: a number beyond the range of a double");
}

TEST(JsonStrict, IntegersBeyondIntAreRefusedNotWrapped) {
  // 4294967297 = 2^32 + 1 was read as 1 ring by get<int>() and ran with exit 0.
  for (const char* big : {"4294967297", "18446744073709551615", "-9223372036854775808", "2147483648"}) {
    const std::string e = ConfigErrorOf(Replaced(kPaper, "\"rings_N\": 11", std::string("\"rings_N\": ") + big));
    EXPECT_NE(e.find("cfg.json: ideal_image.rings_N: must be in ["), std::string::npos) << big << ": " << e;
  }
}

TEST(JsonStrict, DuplicateKeysAreRefused) {
  EXPECT_EQ(ConfigErrorOf(Replaced(kPaper, "\"kx\": -0.43,", "\"kx\": -0.43, \"kx\": 0.5,")),
            "cfg.json: cornea.kx: given twice in one object");
  // The same key in two different objects is fine (ideal_image and cornea both have keys named like this).
  EXPECT_EQ(util::ParseJsonStrict(R"({"a": {"x": 1}, "b": {"x": 2}})", "t.json")["b"]["x"], 2);
  EXPECT_THROW(util::ParseJsonStrict(R"({"a": 1, "b": [{"a": 1}], "a": 2})", "t.json"), util::ConfigError);
}

TEST(JsonStrict, DeepNestingIsRefusedBeforeParsing) {
  // 100000 '[' overflowed the stack of nlohmann's recursive parser and of dump() (SIGSEGV).
  for (const std::string& deep : {std::string(100000, '['), std::string(100000, '[') + std::string(100000, ']'),
                                  "{\"a\":" + std::string(100000, '{')}) {
    try {
      util::ParseJsonStrict(deep, "deep.json");
      ADD_FAILURE() << "accepted";
    } catch (const util::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("deep.json: nested deeper than 64 levels"), std::string::npos) << e.what();
    }
  }
  // Brackets inside strings are not nesting.
  EXPECT_NO_THROW(util::ParseJsonStrict("{\"s\": \"" + std::string(1000, '[') + "\\\"[\"}", "t.json"));
  EXPECT_NO_THROW(
      util::ParseJsonStrict(std::string(util::kMaxJsonDepth, '[') + std::string(util::kMaxJsonDepth, ']'), "t.json"));
}

TEST(JsonStrict, BadValuesAreEchoedShort) {
  const std::string huge(6 << 20, 'x');  // once an error line of 6 MB
  const std::string e = ConfigErrorOf(Replaced(kPaper, "\"rings_N\": 11", "\"rings_N\": \"" + huge + "\""));
  EXPECT_NE(e.find("ideal_image.rings_N: must be an integer"), std::string::npos) << e.substr(0, 200);
  EXPECT_LT(e.size(), 200u);
  const std::string long_key(5000, 'k');
  const std::string dup = R"({")" + long_key + R"(": 1, ")" + long_key + R"(": 2})";
  try {
    util::ParseJsonStrict(dup, "t.json");
    ADD_FAILURE() << "accepted";
  } catch (const util::ConfigError& err) {
    EXPECT_LT(std::string(err.what()).size(), 200u);
  }
}

TEST(JsonStrict, IntegerRangeWithoutTruncation) {
  using nlohmann::json;
  EXPECT_TRUE(util::JsonIntegerWithin(json(5), 0, 10));
  EXPECT_FALSE(util::JsonIntegerWithin(json(4294967297ULL), 0, 10));
  EXPECT_FALSE(util::JsonIntegerWithin(json(18446744073709551615ULL), -1, 2147483647));
  EXPECT_FALSE(util::JsonIntegerWithin(json(-1), 0, 10));
  EXPECT_FALSE(util::JsonIntegerWithin(json(2.5), 0, 10));
}

}  // namespace
}  // namespace topocal::model

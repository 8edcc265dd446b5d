// Tabulated terms of effect files (hw/effect_file.h, "tables"): piecewise-linear (bilinear)
// functions through knots whose knot values are fitted parameters.
//
// Ground truths: interpolation values are hand-computed from the knots (at a knot the table
// gives the knot value bit for bit; between, the weights are exact binary fractions or
// small rationals, checked to 1e-12); a tabulated friction is checked against the same
// piecewise-linear function written as an explicit muParser expression, in the lab's
// prediction and in the simulated catheter (to 1e-9: the two evaluate the same segments with
// differently rounded arithmetic).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "hw/effect_file.h"
#include "hw/effect_registry.h"
#include "hw/simulated_catheter.h"
#include "hw/transmission_model.h"
#include "lab/lab_dataset.h"
#include "lab/model_prediction.h"
#include "tests/hw/effect_test_util.h"
#include "tests/test_util/expect_error.h"

// A namespace of its own: the test target compiles in unity batches with effect_file_test.cc.
namespace echoservo::hw::effect_table_test {
namespace {

using ::echoservo::testing::ExpectContains;
using Names = std::vector<std::string>;
using testing::SineTrial;

constexpr double kTight = 1e-12;

// shape_1 along base_mm: the example of docs/effect_files.md.
EffectTableSpec Shape1() {
  EffectTableSpec t;
  t.name = "shape_1";
  t.inputs = {"base_mm"};
  t.knots = {{-10, -5, 0, 5, 10}};
  t.values = {0.0, 0.1, 0.3, 0.1, 0.0};
  t.unit = "N";
  t.lower = -5;
  t.upper = 5;
  t.doc = "friction along base_mm learnt by lab diagnose";
  return t;
}

// shape_2 along bend_deg × speed_mm_s with v[i][j] = 10·i + j + 5·i·j (not separable, so
// that the bilinear cross term matters).
EffectTableSpec Shape2() {
  EffectTableSpec t;
  t.name = "shape_2";
  t.inputs = {"bend_deg", "speed_mm_s"};
  t.knots = {{90, 180, 270}, {0, 20, 60, 120}};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 4; ++j) t.values.push_back(10.0 * i + j + 5.0 * i * j);
  }
  t.unit = "N";
  t.lower = 0;
  t.upper = 100;
  return t;
}

EffectFileSpec Spec(const std::string& name, std::vector<EffectTableSpec> tables,
                    std::vector<std::pair<std::string, std::string>> expressions) {
  EffectFileSpec s;
  s.name = name;
  s.description = "tabulated test effect";
  s.parameters = {{"a_n", "N", 0.3, 0.0, 5.0, "a plain parameter"}};
  s.tables = std::move(tables);
  s.expressions = std::move(expressions);
  return s;
}

EffectContext AtBendDeg(double deg) {
  EffectContext c;
  c.total_bend_rad = deg * std::numbers::pi / 180.0;
  c.gap_mm = 0.5;
  c.tip_load_n = 0.5;
  return c;
}

std::vector<double> Defaults(const Effect& e) {
  std::vector<double> p;
  for (const ParameterSpec& s : e.parameters()) p.push_back(s.default_value);
  return p;
}

SampleSignals AtBase(double base_mm, double velocity_mm_s = 0.0) {
  SampleSignals s;
  s.base_mm = base_mm;
  s.velocity_mm_s = velocity_mm_s;
  return s;
}

class EffectTableTest : public testing::ScratchFileTest {};

// ------------------------------------------------------------------------- format

TEST_F(EffectTableTest, WriteReadRoundTripGivesTheSpecBack) {
  EffectTableSpec odd = Shape1();
  odd.name = "odd";
  odd.values = {1.0 / 3.0, 0.1, -0.7, 2.0 / 7.0, 1e-17};
  odd.knots = {{-10.25, -1.0 / 3.0, 0, 5e-3, 1e6}};
  odd.doc.clear();
  EffectFileSpec s = Spec("tabulated", {Shape1(), Shape2(), odd},
                          {{"friction_n", "shape_2"}, {"force_n", "shape_1*velocity_mm_s + odd"}});
  s.signature = "a friction shape";
  const std::string path = (dir_ / "t.json").string();
  WriteEffectFile(path, s);
  const EffectFileSpec r = ReadEffectFile(path);
  EXPECT_FALSE(r == s);  // the path differs
  s.path = path;
  EXPECT_TRUE(r == s);
  EXPECT_EQ(r.tables, s.tables);
  EXPECT_EQ(EffectJson(r), EffectJson(s));
  // The format: "tables" between the parameters and the expressions.
  const std::string text = EffectJson(s);
  ExpectContains(text, "\"format\": \"echoservo.effect/1\"");
  EXPECT_LT(text.find("\"parameters\""), text.find("\"tables\""));
  EXPECT_LT(text.find("\"tables\""), text.find("\"expressions\""));
  // Without tables, no "tables" key (files as before).
  s.tables.clear();
  s.expressions = {{"friction_n", "a_n"}};
  EXPECT_EQ(EffectJson(s).find("tables"), std::string::npos);
}

TEST_F(EffectTableTest, ReadsTheDocumentedExample) {
  // docs/effect_files.md, "Tabulated terms".
  const std::string path = Write("tight.json", R"j({
  "format": "echoservo.effect/1",
  "name": "tight",
  "parameters": [],
  "tables": [
    {"name": "shape_1", "inputs": ["base_mm"], "knots": [[-10, -5, 0, 5, 10]],
     "values": [0.0, 0.1, 0.3, 0.1, 0.0], "unit": "N", "lower": -5, "upper": 5,
     "doc": "friction along base_mm learnt by lab diagnose"},
    {"name": "shape_2", "inputs": ["bend_deg", "speed_mm_s"],
     "knots": [[90, 180, 270], [0, 20, 60, 120]],
     "values": [0, 1, 2, 3,  10, 16, 22, 28,  20, 31, 42, 53],
     "unit": "N", "lower": 0, "upper": 100}
  ],
  "expressions": {"friction_n": "shape_1", "force_n": "0.01*shape_2*velocity_mm_s"}
})j");
  const EffectFileSpec s = ReadEffectFile(path);
  ASSERT_EQ(s.tables.size(), 2u);
  EXPECT_EQ(s.tables[0], Shape1());
  EXPECT_EQ(s.tables[1], Shape2());
  const auto e = MakeExpressionEffect(s);
  const std::vector<double> p = Defaults(*e);
  EXPECT_NEAR(e->ForceN(AtBase(0.0, 40.0), AtBendDeg(135), p.data()), 0.01 * 10.25 * 40.0, kTight);
  EXPECT_EQ(e->parameters()[0].name, "shape_1_0");
  EXPECT_EQ(e->parameters()[5].name, "shape_2_0");
}

// ------------------------------------------------------------------ interpolation

TEST_F(EffectTableTest, OneInputInterpolatesLinearlyBetweenKnots) {
  // Natively (the expression is the table) and through muParser (a product, and a sum).
  const auto e = MakeExpressionEffect(
      Spec("t1", {Shape1()}, {{"friction_n", " shape_1 "}, {"force_n", "shape_1*velocity_mm_s"}}));
  const auto sum = MakeExpressionEffect(Spec("t2", {Shape1()}, {{"friction_n", "shape_1 + a_n"}}));
  const std::vector<double> p = Defaults(*e);
  const EffectContext c = AtBendDeg(180);
  const std::vector<std::pair<double, double>> expected = {
      {-10, 0.0},   {-5, 0.1}, {0, 0.3},      {5, 0.1},     {10, 0.0},  // the knots
      {-7.5, 0.05}, {2, 0.22}, {-1.25, 0.25}, {8.75, 0.025}};           // between
  for (const auto& [x, y] : expected) {
    SCOPED_TRACE(x);
    EXPECT_NEAR(e->SignalFrictionN(3.0, AtBase(x), c, p.data()), y, kTight);
    EXPECT_NEAR(e->ForceN(AtBase(x, -4.0), c, p.data()), -4.0 * y, kTight);
    EXPECT_NEAR(sum->SignalFrictionN(3.0, AtBase(x), c, p.data()), y + 0.3, kTight);
  }
  for (const double x : {-10.0, -5.0, 0.0, 5.0, 10.0}) {  // at a knot: bit for bit
    EXPECT_EQ(e->SignalFrictionN(3.0, AtBase(x), c, p.data()),
              Shape1().values[static_cast<std::size_t>((x + 10) / 5)]);
  }
}

TEST_F(EffectTableTest, PairInterpolatesBilinearly) {
  const auto e = MakeExpressionEffect(Spec("t2", {Shape2()}, {{"friction_n", "shape_2"}}));
  const auto twice =
      MakeExpressionEffect(Spec("t3", {Shape2()}, {{"friction_n", "2*shape_2 + a_n"}}));
  const std::vector<double> p = Defaults(*e);
  struct Case {
    double bend_deg, speed_mm_s, value;
  };
  const std::vector<Case> cases = {
      {90, 0, 0.0},         {270, 120, 53.0}, {180, 20, 16.0}, {90, 60, 2.0},  // knots
      {135, 40, 10.25},      // cell (0, 1): (1 + 2 + 16 + 22) / 4
      {225, 90, 36.25},      // cell (1, 2): (22 + 28 + 42 + 53) / 4
      {200, 10, 142.0 / 9},  // cell (1, 0), t = 2/9 and 1/2: 7/9·13 + 2/9·25.5
      {90, 30, 1.25},        // along the first row: 1 + (2 − 1)/4
      {270, 120, 53.0}};
  for (const Case& k : cases) {
    SCOPED_TRACE(std::to_string(k.bend_deg) + " deg, " + std::to_string(k.speed_mm_s) + " mm/s");
    const EffectContext c = AtBendDeg(k.bend_deg);
    EXPECT_NEAR(e->FrictionMagnitudeN(k.speed_mm_s, c, p.data()), k.value, 1e-12 * 100);
    EXPECT_NEAR(twice->FrictionMagnitudeN(k.speed_mm_s, c, p.data()), 2 * k.value + 0.3,
                1e-12 * 100);
  }
  // The whole-trial hook gives the per-sample values bit for bit.
  const std::vector<double> speeds = {0, 5, 20, 33, 60, 119.5, 120};
  std::vector<double> out(speeds.size(), 0.0);
  const EffectContext c = AtBendDeg(200);
  e->AddFrictionMagnitudesN(speeds, c, p.data(), out);
  for (std::size_t i = 0; i < speeds.size(); ++i)
    EXPECT_EQ(out[i], e->FrictionMagnitudeN(speeds[i], c, p.data()));
}

// --------------------------------------------------------------------- parameters

TEST_F(EffectTableTest, KnotValuesAreParametersAfterTheExplicitOnes) {
  const EffectFileSpec s = Spec("t", {Shape1(), Shape2()}, {{"friction_n", "shape_2"}});
  const auto e = MakeExpressionEffect(s);
  const auto params = e->parameters();
  ASSERT_EQ(params.size(), 1u + 5u + 12u);
  EXPECT_EQ(params[0].name, "a_n");
  const std::vector<ParameterSpec> listed = EffectFileParameters(s);
  ASSERT_EQ(listed.size(), params.size());
  for (std::size_t k = 0; k < 5; ++k) {
    const ParameterSpec& q = params[1 + k];
    EXPECT_EQ(q.name, "shape_1_" + std::to_string(k));
    EXPECT_EQ(q.name, TableParameterName("shape_1", k));
    EXPECT_EQ(q.unit, "N");
    EXPECT_EQ(q.default_value, Shape1().values[k]);
    EXPECT_EQ(q.lower, -5.0);
    EXPECT_EQ(q.upper, 5.0);
  }
  ExpectContains(params[1 + 2].doc, "shape_1 at base_mm = 0");
  for (std::size_t k = 0; k < 12; ++k) {
    const ParameterSpec& q = params[6 + k];
    EXPECT_EQ(q.name, "shape_2_" + std::to_string(k));
    EXPECT_EQ(q.default_value, Shape2().values[k]);
    EXPECT_EQ(q.lower, 0.0);
    EXPECT_EQ(q.upper, 100.0);
    EXPECT_EQ(listed[6 + k].name, q.name);
    EXPECT_EQ(listed[6 + k].doc, q.doc);
  }
  ExpectContains(params[6 + 5].doc, "bend_deg = 180, speed_mm_s = 20");  // row 1, column 1
}

TEST_F(EffectTableTest, EvaluationFollowsTheCurrentParameterValues) {
  const auto e = MakeExpressionEffect(
      Spec("t", {Shape1(), Shape2()}, {{"friction_n", "shape_2"}, {"force_n", "shape_1"}}));
  std::vector<double> p = Defaults(*e);
  const EffectContext c = AtBendDeg(135);
  p[1 + 2] = 1.0;   // shape_1 at base 0: 0.3 → 1
  p[6 + 1] = 5.0;   // shape_2 at (90°, 20 mm/s): 1 → 5
  p[6 + 5] = 40.0;  // shape_2 at (180°, 20 mm/s): 16 → 40
  EXPECT_EQ(e->ForceN(AtBase(0.0), c, p.data()), 1.0);
  EXPECT_NEAR(e->ForceN(AtBase(2.5), c, p.data()), 0.5 * 1.0 + 0.5 * 0.1, kTight);
  EXPECT_NEAR(e->FrictionMagnitudeN(20, c, p.data()), 0.5 * 5 + 0.5 * 40, kTight);
  EXPECT_NEAR(e->FrictionMagnitudeN(40, c, p.data()), 0.25 * (5 + 2 + 40 + 22), kTight);

  // Through a model, by qualified name, as the lab's fit sets them.
  EffectRegistry r = EffectRegistry::WithBuiltinEffects();
  RegisterEffectSpec(r, Spec("speed_table", {Shape2()}, {{"friction_n", "shape_2"}}));
  formats::CatheterConfig config = formats::CatheterConfig::SeedEvaluation();
  TransmissionModel m(r, {"speed_table"}, config);
  const double bend = m.config().TotalBendRad() * 180.0 / std::numbers::pi;
  ASSERT_GE(bend, 90.0);
  ASSERT_LE(bend, 270.0);
  const double before = m.FrictionMagnitudeN(60.0);
  for (int i = 0; i < 3; ++i) m.SetParameter("speed_table.shape_2_" + std::to_string(4 * i + 2), 0);
  EXPECT_EQ(m.FrictionMagnitudeN(60.0), 0.0);
  EXPECT_GT(before, 0.0);
}

// ----------------------------------------------------------------- classification

TEST_F(EffectTableTest, ATableAlongSpeedIsPlainFrictionAlongBaseSignalFriction) {
  EffectTableSpec speed = Shape1();
  speed.name = "along_speed";
  speed.inputs = {"speed_mm_s"};
  speed.knots = {{0, 10, 20, 30, 40}};
  const EffectContext c = AtBendDeg(180);
  const auto plain = MakeExpressionEffect(Spec("p", {speed}, {{"friction_n", "along_speed"}}));
  const std::vector<double> p = Defaults(*plain);
  EXPECT_FALSE(plain->UsesSignals());
  EXPECT_NEAR(plain->FrictionMagnitudeN(15, c, p.data()), 0.2, kTight);
  EXPECT_EQ(plain->SignalFrictionN(15, AtBase(0.0, 15), c, p.data()), 0.0);

  // The pair bend × speed is geometry and speed: plain friction too.
  EXPECT_FALSE(
      MakeExpressionEffect(Spec("q", {Shape2()}, {{"friction_n", "shape_2"}}))->UsesSignals());

  const auto signal = MakeExpressionEffect(Spec("s", {Shape1()}, {{"friction_n", "shape_1"}}));
  EXPECT_TRUE(signal->UsesSignals());
  EXPECT_EQ(signal->FrictionMagnitudeN(15, c, p.data()), 0.0);
  EXPECT_NEAR(signal->SignalFrictionN(15, AtBase(2.0, 15), c, p.data()), 0.22, kTight);

  // A table along base_mm makes an expression that otherwise uses speed only signal friction.
  EXPECT_TRUE(MakeExpressionEffect(
                  Spec("m", {Shape1(), speed}, {{"friction_n", "along_speed + 0*shape_1"}}))
                  ->UsesSignals());
  // friction_scale: along bend_deg alone it is a plain scale, along time_s a signal one.
  EffectTableSpec bend = Shape1();
  bend.name = "along_bend";
  bend.inputs = {"bend_deg"};
  bend.knots = {{0, 90, 180, 270, 360}};
  const auto scale =
      MakeExpressionEffect(Spec("b", {bend}, {{"friction_scale", "1 + along_bend"}}));
  EXPECT_FALSE(scale->UsesSignals());
  EXPECT_NEAR(scale->FrictionScale(AtBendDeg(180), p.data()), 1.3, kTight);
  bend.inputs = {"time_s"};
  EXPECT_TRUE(MakeExpressionEffect(Spec("b2", {bend}, {{"friction_scale", "1 + along_bend"}}))
                  ->UsesSignals());
}

// ----------------------------------------------------------------------- errors

TEST_F(EffectTableTest, OutOfRangeAtUseThrowsNamingFileTableInputValueAndRange) {
  const std::string path =
      Write("tight.json", EffectJson(Spec("tight", {Shape1(), Shape2()},
                                          {{"friction_n", "shape_1"}, {"force_n", "shape_2"}})));
  const auto e = MakeExpressionEffect(ReadEffectFile(path));
  const std::vector<double> p = Defaults(*e);
  const EffectContext c = AtBendDeg(180);
  std::string message;
  try {
    e->SignalFrictionN(1.0, AtBase(12.3), c, p.data());
    ADD_FAILURE() << "12.3 mm was accepted";
  } catch (const EffectTableRangeError& x) {
    message = x.what();
  }
  EXPECT_EQ(message, path +
                         ": table shape_1: base_mm = 12.3 is outside its knots [-10, 10] (a "
                         "tabulated term does not extrapolate; learn it on data that covers "
                         "this range)");
  // Below the first knot, in the whole-trial form, as an EffectFileError.
  const std::vector<double> t = {0, 1}, base = {0, -10.5}, v = {1, 1}, a = {0, 0};
  std::vector<double> out(2, 0.0);
  const TrialSignals s{t, base, v, a};
  const std::vector<double> speed = {1, 1};
  ExpectContains(::echoservo::testing::InvalidArgumentMessage(
                     [&] { e->AddSignalFrictionsN(speed, s, c, p.data(), out); }),
                 "base_mm = -10.5 is outside its knots [-10, 10]");
  // Within 1e-9 of the knot span: accepted as the end value.
  EXPECT_EQ(e->SignalFrictionN(1.0, AtBase(10.0 + 1e-10 * 20), c, p.data()), 0.0);
  EXPECT_THROW(e->SignalFrictionN(1.0, AtBase(10.0 + 1e-8 * 20), c, p.data()),
               EffectTableRangeError);
  EXPECT_THROW(e->SignalFrictionN(1.0, AtBase(std::nan("")), c, p.data()), EffectTableRangeError);
  // A geometry input: the trial's bend outside the knots, and a speed beyond the last.
  try {
    e->ForceN(AtBase(0.0, 10.0), AtBendDeg(45), p.data());
    ADD_FAILURE() << "45 deg was accepted";
  } catch (const EffectFileError& x) {
    message = x.what();
  }
  ExpectContains(message, path + ": table shape_2: bend_deg = 45 is outside its knots [90, 270]");
  ExpectContains(::echoservo::testing::InvalidArgumentMessage(
                     [&] { e->ForceN(AtBase(0.0, -130.0), AtBendDeg(180), p.data()); }),
                 "table shape_2: speed_mm_s = 130 is outside its knots [0, 120]");
}

TEST_F(EffectTableTest, TypicalInputsOutsideTheKnotsAreClampedForTheFiniteCheck) {
  // Typical speed 10 mm/s and base 1 mm lie outside these knots: still accepted, and the
  // finite check still bites through the clamped value (1/(shape − 0.5) with shape = 0.5).
  EffectTableSpec t = Shape1();
  t.knots = {{5, 6, 7, 8, 9}};
  t.values = {0.5, 1, 1, 1, 1};
  EffectTableSpec u = t;
  u.name = "fast";
  u.inputs = {"speed_mm_s"};
  u.knots = {{20, 30, 40, 50, 60}};
  EXPECT_NO_THROW(ReadEffectFile(
      Write("ok.json", EffectJson(Spec("ok", {t, u}, {{"friction_n", "shape_1 + fast"}})))));
  const std::string bad =
      Write("bad.json", EffectJson(Spec("bad", {t}, {{"friction_n", "1/(shape_1 - 0.5)"}})));
  std::string message;
  try {
    ReadEffectFile(bad);
  } catch (const EffectFileError& x) {
    message = x.what();
  }
  ExpectContains(message, bad + ": expressions.friction_n: '1/(shape_1 - 0.5)' is inf");
}

TEST_F(EffectTableTest, AHookWithoutATablesInputIsRefused) {
  const EffectFileSpec s = Spec("h", {Shape1()}, {{"drive_offset_mm", "shape_1*force_n"}});
  const std::string path = Write("h.json", EffectJson(s));
  const std::string message =
      ::echoservo::testing::InvalidArgumentMessage([&] { ReadEffectFile(path); });
  ExpectContains(message, path +
                              ": expressions.drive_offset_mm: table shape_1 needs input "
                              "base_mm, which hook drive_offset_mm does not have");
  // In memory too (the origin is the name).
  ExpectContains(::echoservo::testing::InvalidArgumentMessage([&] { MakeExpressionEffect(s); }),
                 "h: expressions.drive_offset_mm: table shape_1 needs input base_mm");
  // A parameters-only hook can use no table.
  ExpectContains(::echoservo::testing::InvalidArgumentMessage([&] {
                   MakeExpressionEffect(Spec("h2", {Shape1()}, {{"sensor_delay_s", "shape_1"}}));
                 }),
                 "hook sensor_delay_s does not have (its inputs: none)");
}

struct BadCase {
  BadCase(std::string t, std::string k, std::string w, std::string p = "",
          std::string e = R"j("friction_n": "a_n")j")
      : tables(std::move(t)),
        key(std::move(k)),
        why(std::move(w)),
        params(std::move(p)),
        exprs(std::move(e)) {}
  std::string tables;  // the "tables" value
  std::string key;
  std::string why;
  std::string params;  // more parameters after a_n
  std::string exprs;
};

std::string TableDoc(const BadCase& c) {
  std::string params = R"j({"name": "a_n", "unit": "N", "default": 0.3, "lower": 0, "upper": 5})j";
  if (!c.params.empty()) params += ", " + c.params;
  return R"j({"format": "echoservo.effect/1", "name": "bad", "parameters": [)j" + params +
         R"j(], "tables": )j" + c.tables + R"j(, "expressions": {)j" + c.exprs + "}}";
}

// shape_1 of Shape1() as JSON with fields replaced (an empty value removes the field, an
// unknown one is added): Table({{"knots", "[[0, 1]]"}}).
std::string Table(const std::vector<std::pair<std::string, std::string>>& changes = {}) {
  std::vector<std::pair<std::string, std::string>> f = {{"name", R"j("shape_1")j"},
                                                        {"inputs", R"j(["base_mm"])j"},
                                                        {"knots", "[[-10, -5, 0, 5, 10]]"},
                                                        {"values", "[0, 0.1, 0.3, 0.1, 0]"},
                                                        {"unit", R"j("N")j"},
                                                        {"lower", "-5"},
                                                        {"upper", "5"}};
  for (const auto& change : changes) {
    auto it =
        std::find_if(f.begin(), f.end(), [&](const auto& kv) { return kv.first == change.first; });
    if (it == f.end()) {
      f.push_back(change);
    } else {
      it->second = change.second;
    }
  }
  std::string out;
  for (const auto& [k, v] : f) {
    if (!v.empty()) out += (out.empty() ? "" : ", ") + ("\"" + k + "\": " + v);
  }
  return "[{" + out + "}]";
}

// The tables of two Table() arrays in one array.
std::string Both(const std::string& a, const std::string& b) {
  return a.substr(0, a.size() - 1) + ", " + b.substr(1);
}

TEST_F(EffectTableTest, EveryBadTableNamesTheFileTheKeyAndWhy) {
  const std::string pair = R"j(["bend_deg", "speed_mm_s"])j";
  const std::vector<BadCase> cases = {
      {"{}", "tables", "must be an array"},
      {"[1]", "tables[0]", "must be an object"},
      {Table({{"colour", "1"}}), "tables[0].colour", "unknown key"},
      {Table({{"unit", ""}}), "tables[0]", "missing key 'unit'"},
      {Table({{"name", R"j("Shape")j"}}), "tables[0].name", "lowercase"},
      {Table({{"name", R"j("a_n")j"}}), "tables[0].name", "name of a parameter"},
      {Table({{"name", R"j("base_mm")j"}}), "tables[0].name", "shadows an input"},
      {Table({{"name", R"j("pi")j"}}), "tables[0].name", "shadows an input"},
      {Both(Table(), Table()), "tables[1].name", "duplicate table name 'shape_1'"},
      {Table(), "tables[0].name", "knot parameter 'shape_1_3'",
       R"j({"name": "shape_1_3", "unit": "N", "default": 0, "lower": -1, "upper": 1})j"},
      {Both(Table(), Table({{"name", R"j("shape_1_2")j"}})), "tables[1].name", "clash"},
      {Table({{"inputs", "[]"}}), "tables[0].inputs", "must name 1 or 2 hook inputs"},
      {Table({{"inputs", R"j(["base_mm", "time_s", "tip_mm"])j"}}), "tables[0].inputs",
       "must name 1 or 2 hook inputs (it names 3)"},
      {Table({{"inputs", R"j("base_mm")j"}}), "tables[0].inputs", "must be an array"},
      {Table({{"inputs", R"j(["speed"])j"}}), "tables[0].inputs[0]",
       "unknown input 'speed' (known: "},
      {Table({{"inputs", R"j(["base_mm", "base_mm"])j"}}), "tables[0].inputs[1]", "named twice"},
      {Table({{"inputs", pair}}), "tables[0].knots",
       "one array of knots per input (2 inputs, 1 arrays)"},
      {Table({{"knots", "[[0]]"}}), "tables[0].knots[0]", "at least 2 knots"},
      {Table({{"knots", "[[-10, -5, 5, 0, 10]]"}}), "tables[0].knots[0]",
       "unsorted: knot 0 at index 3 is below 5"},
      {Table({{"knots", "[[-10, -5, 5, 5, 10]]"}}), "tables[0].knots[0]",
       "duplicated knot 5 at index 3"},
      {Table({{"knots", R"j([[-10, -5, "0", 5, 10]])j"}}), "tables[0].knots[0][2]",
       "must be a number"},
      {Table({{"knots", "[-10, -5, 0, 5, 10]"}}), "tables[0].knots[0]",
       "must be an array of numbers"},
      {Table({{"inputs", pair}, {"knots", "[[90, 180], [0, 60, 20]]"}}), "tables[0].knots[1]",
       "unsorted: knot 20 at index 2"},
      {Table({{"values", "[0, 0.1, 0.3, 0.1]"}}), "tables[0].values", "holds 4 values, expected 5"},
      {Table({{"values", "[0, 0.1, 7, 0.1, 0]"}}), "tables[0].values[2]",
       "7 is outside the bounds [-5, 5]"},
      {Table({{"values", "0"}}), "tables[0].values", "must be an array of numbers"},
      {Table({{"upper", "-5"}}), "tables[0].upper", "must be greater than lower -5"},
      {Table({{"unit", R"j("")j"}}), "tables[0].unit", "must not be empty"},
      {Table({{"doc", "3"}}), "tables[0].doc", "must be a string"},
      {Table(), "expressions.drive_offset_mm",
       "table shape_1 needs input base_mm, which hook drive_offset_mm does not have", "",
       R"j("drive_offset_mm": "shape_1")j"},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const std::string path = Write("bad" + std::to_string(i) + ".json", TableDoc(cases[i]));
    std::string message;
    try {
      ReadEffectFile(path);
      ADD_FAILURE() << "case " << i << " was accepted: " << TableDoc(cases[i]);
      continue;
    } catch (const EffectFileError& e) {
      message = e.what();
    }
    SCOPED_TRACE("case " + std::to_string(i));
    ExpectContains(message, path + ": " + cases[i].key + ": ");
    ExpectContains(message, cases[i].why);
  }
  // What JSON cannot hold, a spec in memory can: MakeExpressionEffect checks it as well.
  EffectTableSpec t = Shape1();
  t.values[1] = std::nan("");
  ExpectContains(::echoservo::testing::InvalidArgumentMessage([&] {
                   MakeExpressionEffect(Spec("mem", {t}, {{"friction_n", "shape_1"}}));
                 }),
                 "mem: tables[0].values[1]: must be finite");
  t = Shape1();
  t.knots[0][4] = 5;
  ExpectContains(::echoservo::testing::InvalidArgumentMessage([&] {
                   MakeExpressionEffect(Spec("mem", {t}, {{"friction_n", "shape_1"}}));
                 }),
                 "mem: tables[0].knots[0]: duplicated knot 5 at index 4");
}

// ----------------------------------------------------------------- end to end

// Speed: 0.1 N at rest rising to 0.2 N at 20 mm/s, 0.15 N at 60, 0.4 N at 2000 mm/s.
EffectTableSpec SpeedShape() {
  EffectTableSpec t;
  t.name = "shape";
  t.inputs = {"speed_mm_s"};
  t.knots = {{0, 20, 60, 2000}};
  t.values = {0.1, 0.2, 0.15, 0.4};
  t.unit = "N";
  t.lower = 0;
  t.upper = 2;
  return t;
}
const char* kSpeedPiecewise =
    "speed_mm_s < 20 ? 0.1 + (0.2 - 0.1)*speed_mm_s/20 : (speed_mm_s < 60 ? "
    "0.2 + (0.15 - 0.2)*(speed_mm_s - 20)/40 : 0.15 + (0.4 - 0.15)*(speed_mm_s - 60)/1940)";
// Base: a tight spot 0.3 N high between −1 and 3 mm, peaking at 1 mm.
EffectTableSpec BaseShape() {
  EffectTableSpec t;
  t.name = "spot";
  t.inputs = {"base_mm"};
  t.knots = {{-1000, -1, 1, 3, 1000}};
  t.values = {0, 0, 0.3, 0, 0};
  t.unit = "N";
  t.lower = 0;
  t.upper = 2;
  return t;
}
const char* kBasePiecewise =
    "base_mm < -1 ? 0 : (base_mm < 1 ? 0.3*(base_mm + 1)/2 : (base_mm < 3 ? 0.3*(3 - base_mm)/2 "
    ": 0))";

EffectRegistry TabulatedAndExplicit() {
  EffectRegistry r = EffectRegistry::WithBuiltinEffects();
  EffectFileSpec tab;
  tab.name = "tab_friction";
  tab.tables = {SpeedShape(), BaseShape()};
  tab.expressions = {{"friction_n", "shape"}};
  RegisterEffectSpec(r, tab);
  tab.name = "tab_spot";
  tab.expressions = {{"friction_n", "spot"}};
  RegisterEffectSpec(r, tab);
  EffectFileSpec ex;
  ex.name = "explicit_friction";
  ex.expressions = {{"friction_n", kSpeedPiecewise}};
  RegisterEffectSpec(r, ex);
  ex.name = "explicit_spot";
  ex.expressions = {{"friction_n", kBasePiecewise}};
  RegisterEffectSpec(r, ex);
  return r;
}

TEST_F(EffectTableTest, TabulatedFrictionPredictsAsTheExplicitPiecewiseExpression) {
  const EffectRegistry r = TabulatedAndExplicit();
  const lab::LabTrial trial = SineTrial();
  const auto predict = [&](const Names& effects) {
    TransmissionModel m(r, effects, trial.trial.config);
    lab::Prediction p;
    lab::PredictTrial(m, trial, {0.1, 0.3}, p);
    return p;
  };
  const auto a = predict({"coulomb_friction", "backlash", "tab_friction", "tab_spot"});
  const auto b = predict({"coulomb_friction", "backlash", "explicit_friction", "explicit_spot"});
  const auto none = predict({"coulomb_friction", "backlash"});
  ASSERT_EQ(a.force_n.size(), b.force_n.size());
  double differs = 0.0;
  for (std::size_t i = 0; i < a.force_n.size(); ++i) {
    ASSERT_NEAR(a.tip_mm[i], b.tip_mm[i], 1e-9) << i;
    ASSERT_NEAR(a.force_n[i], b.force_n[i], 1e-9) << i;
    differs = std::max(differs, std::abs(a.force_n[i] - none.force_n[i]));
  }
  EXPECT_GT(differs, 0.1);  // the tables took part
  TransmissionModel m(r, {"tab_friction"}, trial.trial.config);
  EXPECT_FALSE(m.UsesSignals());
  EXPECT_NEAR(m.FrictionLevelN(), 0.1, kTight);
  EXPECT_NEAR(m.FrictionMagnitudeN(40.0), 0.175, kTight);
}

TEST_F(EffectTableTest, TabulatedFrictionSimulatesAsTheExplicitPiecewiseExpression) {
  const EffectRegistry r = TabulatedAndExplicit();
  const auto run = [&](const Names& effects) { return testing::RunPlantSine(r, effects, false); };

  const auto a = run({"coulomb_friction", "backlash", "tab_friction", "tab_spot"});
  const auto b = run({"coulomb_friction", "backlash", "explicit_friction", "explicit_spot"});
  const auto none = run({"coulomb_friction", "backlash"});
  double moved = 0.0, differs = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(a[i][k], b[i][k], 1e-9) << i << " " << k;
    moved = std::max(moved, std::abs(a[i][2] - a.front()[2]));
    differs = std::max(differs, std::abs(a[i][2] - none[i][2]));
  }
  EXPECT_GT(moved, 0.1);
  EXPECT_GT(differs, 0.0);
}

}  // namespace
}  // namespace echoservo::hw::effect_table_test

// `lab diagnose` in an open world (lab/diagnosis.h, lab/effect_discovery.h): data recorded
// in-process by the simulated catheter with an effect defined in an effect FILE, outside
// the catalog the lab fits from.
//  (a) Guidewire inertia, force_n = m·a: the seed model is "unexplained" (no catalog effect
//      is significant), the force residual varies most with acceleration_mm_s2, and the
//      proposed effect (written to a scratch folder) brings the held-out force RMS down to
//      the noise, reads back as an effect file, resolves as a SPEC and recovers m.
//  (b) A drifting tip sensor, sensor_offset_mm = d·t: the same on the tip channel along
//      time_s.
//  (c) Seed data: "adequate", no variable of `where` explains min_structure.
//  (d) A catalog effect (sensor_delay): "missing_effect" naming it, no proposal.
//  (e) A swap: a wrong effect in the model is replaced, in Diagnose and in ErrorLadder.
//
// Datasets (small, to keep the suite fast): the seed catheter with tip loads 0 and 1 N,
// the 1.2 Hz ±4 mm sine and the mitral trajectory, 2 s each (4 trials, 8000 samples; for
// the drift and the swap the sine only, 2 trials); the simulator's noise is 0.03 mm (tip)
// and 0.0075 N (force), 1σ. Effect sizes:
//  - inertia m = 0.12 kg: on the sine alone a_rms = 4·(2π·1.2)²/√2 ≈ 160 mm/s², so
//    m·a ≈ 0.019 N RMS ≈ 6.6 force noise variances (the mitral trajectory accelerates
//    harder; the simulator's acceleration is the slide's over the last substep, rougher
//    still during stick-slip, which also raises the dataset's force noise floor estimate).
//  - drift d = 0.15 mm/s: after each trial's tip offset is fitted the residual is
//    d·(t − 1 s) over 2 s, RMS d/√3 ≈ 0.087 mm ≈ 8.3 tip noise variances.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "control/experiments/record_experiment.h"
#include "hw/effect_file.h"
#include "hw/effect_registry.h"
#include "lab/diagnosis.h"
#include "lab/model_fit.h"
#include "tests/lab/lab_test_util.h"

namespace echoservo::lab::open_world_test {
namespace {

namespace fs = std::filesystem;
using testing::Recording;
using testing::ScratchDir;

constexpr char kInertia[] = R"({
  "format": "echoservo.effect/1",
  "name": "guidewire_inertia",
  "description": "The guidewire's mass: the base must accelerate it, the force sensor reads m*a.",
  "signature": "force residual proportional to acceleration",
  "parameters": [{"name": "m_kg", "unit": "kg", "default": 0.12, "lower": 0, "upper": 1}],
  "expressions": {"force_n": "m_kg*acceleration_mm_s2*1e-3"}
})";

constexpr char kDrift[] = R"({
  "format": "echoservo.effect/1",
  "name": "tip_sensor_drift",
  "description": "The tip sensor's zero drifts linearly in time.",
  "signature": "tip residual growing linearly within every trial",
  "parameters": [{"name": "d_mm_per_s", "unit": "mm/s", "default": 0.15, "lower": -1, "upper": 1}],
  "expressions": {"sensor_offset_mm": "d_mm_per_s*time_s"}
})";

// A tip-sensor latency that cannot be switched off (≥ 4 ms): a wrong effect for data whose
// tip sensor has a gain error instead. On the 1.2 Hz ±4 mm sine the tip speed is
// ≈ 21 mm/s RMS, so 4 ms leave ≈ 0.085 mm RMS, ≈ 8 tip noise variances.
constexpr char kLag[] = R"({
  "format": "echoservo.effect/1",
  "name": "tip_sensor_lag",
  "description": "A filter in the tip sensor's read-out delays it.",
  "signature": "tip residual proportional to tip velocity",
  "parameters": [{"name": "delay_s", "unit": "s", "default": 0.01, "lower": 0.004, "upper": 0.05}],
  "expressions": {"sensor_delay_s": "delay_s"}
})";

fs::path WriteText(const fs::path& dir, const std::string& name, const std::string& text) {
  fs::create_directories(dir);
  const fs::path path = dir / name;
  std::ofstream(path) << text;
  return path;
}

Recording SmallRecording(const std::string& effects,
                         std::vector<std::string> trajectories = {"sine:4:1.2", "mitral"}) {
  Recording r;
  r.effects = effects;
  r.configs = "seed";
  r.trajectories = std::move(trajectories);
  r.tip_loads_n = {0.0, 1.0};
  r.duration_s = 2.0;
  return r;
}

LabDataset RecordOpenWorld(const Recording& r, hw::EffectRegistry& registry) {
  return testing::RecordResolved(r, registry);
}

std::string Fixed4(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.4f", v);
  return buf;
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

std::string Describe(const Diagnosis& d) {
  std::string s = d.verdict + ": " + d.summary + "\n where:";
  for (const WhereEntry& e : d.where)
    s += "\n  " + e.channel + " " + e.variable + " " + std::to_string(e.gain);
  s += "\n candidates:";
  for (const Candidate& c : d.candidates) {
    s += "\n  " + (c.replaces.empty() ? "" : "-" + c.replaces) + "+" + c.effect +
         (c.significant ? " significant" : "") + " score " + std::to_string(c.score);
  }
  return s;
}

const WhereEntry* TopWhere(const Diagnosis& d, const std::string& channel) {
  for (const WhereEntry& e : d.where)
    if (e.channel == channel) return &e;
  return nullptr;
}

// The summary carries both channels' held-out RMS against the dataset's noise, as
// Diagnose computes them: sqrt(held-out mean square in noise variances) × noise.
void ExpectChannelFigures(const Diagnosis& d, const LabDataset& ds) {
  const double tip = std::sqrt(std::max(d.base_cv.tip_mse, 0.0)) * ds.noise.tip_mm;
  const double force = std::sqrt(std::max(d.base_cv.force_mse, 0.0)) * ds.noise.force_n;
  EXPECT_TRUE(Contains(d.summary, "tip held-out RMS " + Fixed4(tip) + " mm against noise " +
                                      Fixed4(ds.noise.tip_mm) + " mm"))
      << d.summary;
  EXPECT_TRUE(Contains(d.summary, "force held-out RMS " + Fixed4(force) + " N against noise " +
                                      Fixed4(ds.noise.force_n) + " N"))
      << d.summary;
}

// ---------------------------------------------------------------------- beyond the catalog

struct OpenWorldEffect {
  const char* name;
  const char* file_text;
  const char* channel;   // where the effect shows: "tip" or "force"
  const char* variable;  // the `where` variable it lives along
  const char* hook;      // the hook a proposal must use
  double truth;          // the effect's coefficient (its file default)
  std::vector<std::string> trajectories;
};

void PrintTo(const OpenWorldEffect& e, std::ostream* os) { *os << e.name; }

class UnexplainedEffect : public ::testing::TestWithParam<OpenWorldEffect> {};

TEST_P(UnexplainedEffect, IsLocatedAndProposedAndTheProposalReadsBack) {
  const OpenWorldEffect& p = GetParam();
  ScratchDir scratch("open_world");
  const fs::path file = WriteText(scratch.path(), std::string(p.name) + ".json", p.file_text);
  hw::EffectRegistry sim_registry = hw::EffectRegistry::WithBuiltinEffects();
  const LabDataset ds =
      RecordOpenWorld(SmallRecording("seed+@" + file.string(), p.trajectories), sim_registry);
  ASSERT_EQ(ds.trials.size(), 2 * p.trajectories.size());

  // The lab fits from the built-in catalog: the effect is not among its candidates.
  DiagnoseOptions o;
  o.propose_dir = scratch.path() / "proposal";
  const Diagnosis d = Diagnose(hw::SeedEffects(), ds, o);
  EXPECT_EQ(d.verdict, "unexplained") << Describe(d);
  EXPECT_FALSE(d.adequate);
  for (const Candidate& c : d.candidates) EXPECT_FALSE(c.significant) << Describe(d);

  const bool tip = std::string(p.channel) == "tip";
  const double noise = tip ? ds.noise.tip_mm : ds.noise.force_n;
  EXPECT_GE(tip ? d.tip_excess : d.force_excess, o.min_excess) << Describe(d);
  const WhereEntry* top = TopWhere(d, p.channel);
  ASSERT_NE(top, nullptr);
  EXPECT_EQ(top->variable, p.variable) << Describe(d);
  EXPECT_GE(top->gain, o.min_structure) << Describe(d);
  ExpectChannelFigures(d, ds);
  EXPECT_TRUE(
      Contains(d.summary, std::string(p.channel) + " residual varies most with " + p.variable))
      << d.summary;

  // The proposal: one term on the right hook, along the right variable, with the effect's
  // coefficient (±10 %), and the held-out RMS of the affected channel back to ≤ 1.5× the
  // noise (the other channel no worse than that either).
  ASSERT_TRUE(d.proposal.has_value()) << Describe(d);
  const Proposal& prop = *d.proposal;
  EXPECT_TRUE(Contains(d.summary, "proposed: " + prop.equation)) << d.summary;
  ASSERT_FALSE(prop.effect.expressions.empty());
  EXPECT_EQ(prop.effect.expressions.front().first, p.hook);
  EXPECT_TRUE(Contains(prop.effect.expressions.front().second, p.variable))
      << prop.effect.expressions.front().second;
  ASSERT_FALSE(prop.effect.parameters.empty());
  EXPECT_NEAR(prop.effect.parameters.front().default_value, p.truth, 0.1 * p.truth)
      << prop.equation;
  const double rms = tip ? prop.rms_mm : prop.force_rms_n;
  EXPECT_LE(rms, 1.5 * noise) << prop.equation;
  EXPECT_LE(prop.rms_mm, 1.5 * ds.noise.tip_mm);
  EXPECT_LE(prop.force_rms_n, 1.5 * ds.noise.force_n);
  EXPECT_LT(tip ? prop.cv.tip_mse : prop.cv.force_mse,
            tip ? d.base_cv.tip_mse : d.base_cv.force_mse);

  // The file is in the scratch folder, reads back as the same effect, and its SPEC resolves
  // in a fresh catalog to the seed's effects plus the file's.
  ASSERT_FALSE(prop.file.empty());
  EXPECT_EQ(fs::path(prop.file).parent_path(), o.propose_dir);
  const hw::EffectFileSpec back = hw::ReadEffectFile(prop.file);
  EXPECT_EQ(back.name, prop.effect.name);
  EXPECT_EQ(back.expressions, prop.effect.expressions);
  ASSERT_EQ(back.parameters.size(), prop.effect.parameters.size());
  for (std::size_t i = 0; i < back.parameters.size(); ++i) {
    EXPECT_EQ(back.parameters[i].name, prop.effect.parameters[i].name);
    EXPECT_DOUBLE_EQ(back.parameters[i].default_value, prop.effect.parameters[i].default_value);
  }
  hw::EffectRegistry lab_registry = hw::EffectRegistry::WithBuiltinEffects();
  const std::vector<std::string> effects = hw::ResolveModelSpec(prop.spec, lab_registry);
  std::vector<std::string> want = hw::SeedEffects();
  want.push_back(prop.effect.name);
  EXPECT_EQ(effects, want) << prop.spec;
  EXPECT_EQ(lab_registry.Source(prop.effect.name), prop.file);
  EXPECT_EQ(effects, prop.effects);
  // The model the SPEC names predicts as the proposal's fit did (same parameters).
  FitOptions fo;
  fo.registry = &lab_registry;
  const FitResult again = EvaluateModel(effects, prop.fit.parameters, ds, fo, {});
  EXPECT_NEAR(again.tip_mse_norm, prop.fit.tip_mse_norm, 0.01 * prop.fit.tip_mse_norm);
  EXPECT_NEAR(again.force_mse_norm, prop.fit.force_mse_norm, 0.01 * prop.fit.force_mse_norm);
}

INSTANTIATE_TEST_SUITE_P(
    EffectFiles, UnexplainedEffect,
    ::testing::Values(
        OpenWorldEffect{"guidewire_inertia",
                        kInertia,
                        "force",
                        "acceleration_mm_s2",
                        "force_n",
                        0.12,
                        {"sine:4:1.2", "mitral"}},
        OpenWorldEffect{
            "tip_sensor_drift", kDrift, "tip", "time_s", "sensor_offset_mm", 0.15, {"sine:4:1.2"}}),
    [](const ::testing::TestParamInfo<OpenWorldEffect>& info) {
      return std::string(info.param.name);
    });

TEST(OpenWorldDiagnosis, SeedDataIsAdequateWithNoStructureLeft) {
  hw::EffectRegistry registry = hw::EffectRegistry::WithBuiltinEffects();
  const LabDataset ds = RecordOpenWorld(SmallRecording("seed"), registry);
  DiagnoseOptions o;
  const Diagnosis d = Diagnose(hw::SeedEffects(), ds, o);
  EXPECT_EQ(d.verdict, "adequate") << Describe(d);
  EXPECT_TRUE(d.adequate);
  EXPECT_FALSE(d.proposal.has_value());
  ASSERT_FALSE(d.where.empty());
  for (const WhereEntry& e : d.where)
    EXPECT_LT(e.gain, o.min_structure) << e.channel << " " << e.variable;
  EXPECT_LT(d.tip_excess, o.min_excess);
  EXPECT_LT(d.force_excess, o.min_excess);
  ExpectChannelFigures(d, ds);
}

TEST(OpenWorldDiagnosis, ACatalogEffectIsStillAMissingEffect) {
  hw::EffectRegistry registry = hw::EffectRegistry::WithBuiltinEffects();
  const LabDataset ds = RecordOpenWorld(SmallRecording("seed+sensor_delay"), registry);
  const Diagnosis d = Diagnose(hw::SeedEffects(), ds, DiagnoseOptions{});
  EXPECT_EQ(d.verdict, "missing_effect") << Describe(d);
  ASSERT_FALSE(d.candidates.empty());
  EXPECT_EQ(d.candidates.front().effect, "sensor_delay") << Describe(d);
  EXPECT_TRUE(d.candidates.front().significant);
  EXPECT_TRUE(d.candidates.front().replaces.empty());
  EXPECT_TRUE(Contains(d.summary, "missing effect: sensor_delay")) << d.summary;
  EXPECT_FALSE(d.proposal.has_value());  // discovery only where the catalog ends
}

// ---------------------------------------------------------------------- swaps

// A wrong effect in the model, replaced by the catalog effect the data hold. The data:
// seed + tip_sensor_scale (gain 1.03); the model: seed + tip_sensor_lag (an effect file
// whose latency cannot be switched off, ≥ 4 ms). Adding tip_sensor_scale leaves the lag's
// error (≈ 8 noise variances, kLag); replacing the lag by it removes both, so the swap ranks
// first, ahead of the addition by more than a noise variance.
// Why an effect file: every catalog effect can be switched off by its own parameters
// (μ = 0, delay 0, scale 1, …), so with a catalog effect as the wrong one "add" fits as
// well as "swap" and the two differ by noise: model seed + capstan_friction on
// stribeck_friction data, guidewire_compliance on friction_backlash data, deadzone_traversal
// on sensor_delay data (lab configs, mitral, 2 s, seeds 1–2) put the swap ahead of the
// addition by 0.001–0.003 noise variances, and sensor_delay on deadzone_traversal data put
// the addition ahead by 0.005: not a ranking a test can rely on.
// The error ladder swaps only what it added itself: ErrorLadder starts its list of
// swappable effects from options.swappable, which is how a ladder that had added
// tip_sensor_lag in an earlier round goes on. A ladder that adds a wrong catalog effect and
// later replaces it needs the near-tie above, so it is not tested.
TEST(OpenWorldDiagnosis, AWrongEffectIsSwappedOutAndTheLadderEndsWithoutIt) {
  ScratchDir scratch("open_world_swap");
  const fs::path lag = WriteText(scratch.path(), "tip_sensor_lag.json", kLag);
  hw::EffectRegistry registry = hw::EffectRegistry::WithBuiltinEffects();
  const LabDataset ds =
      RecordOpenWorld(SmallRecording("seed+tip_sensor_scale", {"sine:4:1.2"}), registry);
  const std::vector<std::string> model = hw::ResolveModelSpec("seed+@" + lag.string(), registry);
  DiagnoseOptions o;
  o.fit.registry = &registry;
  o.swappable = {"tip_sensor_lag"};
  o.discover = false;
  const std::vector<LadderStep> ladder = ErrorLadder(model, ds, o);

  ASSERT_GE(ladder.size(), 1u);
  const Diagnosis& d = ladder.front().diagnosis;
  ASSERT_FALSE(d.candidates.empty());
  const Candidate& best = d.candidates.front();
  EXPECT_EQ(best.effect, "tip_sensor_scale") << Describe(d);
  EXPECT_EQ(best.replaces, "tip_sensor_lag") << Describe(d);
  EXPECT_TRUE(best.significant) << Describe(d);
  EXPECT_EQ(best.channel, "tip");
  EXPECT_EQ(d.verdict, "missing_effect");
  EXPECT_TRUE(Contains(d.summary, "tip_sensor_scale (replacing tip_sensor_lag)")) << d.summary;
  // Adding the gain to the lag is worse than replacing the lag with it.
  const auto add = std::find_if(d.candidates.begin(), d.candidates.end(), [](const Candidate& c) {
    return c.effect == "tip_sensor_scale" && c.replaces.empty();
  });
  ASSERT_NE(add, d.candidates.end());
  EXPECT_GT(best.score, add->score + 1.0) << Describe(d);
  // The swap leaves only noise in the tip channel.
  EXPECT_LT(best.cv.tip_mse, 1.0 + o.min_excess) << Describe(d);

  ASSERT_EQ(ladder.size(), 2u) << Describe(ladder.back().diagnosis);
  const std::vector<std::string> want =
      hw::ParseModelSpec("seed+tip_sensor_scale", hw::EffectRegistry::WithBuiltinEffects());
  EXPECT_EQ(ladder.back().model, want);
  EXPECT_TRUE(ladder.back().diagnosis.adequate) << Describe(ladder.back().diagnosis);
}

}  // namespace
}  // namespace echoservo::lab::open_world_test

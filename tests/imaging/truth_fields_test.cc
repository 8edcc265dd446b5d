// Ground truth travels with recordings: the per-frame fields round trip, bad values are
// rejected naming the field, and a simulated recording read back through OpenRecording
// carries, frame by frame, the truth the scanner produced.
#include "imaging/io/truth_fields.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "imaging/io/plus_sequence.h"
#include "imaging/io/recording.h"
#include "imaging/sim/simulated_scanner.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::imaging {
namespace {

using ::echoservo::testing::ExpectContains;
using ::echoservo::testing::InvalidArgumentMessage;

FrameGroundTruth Sample() {
  FrameGroundTruth t;
  t.catheter_visible = true;
  t.axis_point_mm = {1.25, -2.5, 60.125};
  t.axis_direction = Eigen::Vector3d(1.0, 0.2, 0.1).normalized();
  t.tip_mm = {3.5, -2.0, 61.0};
  t.target_visible = false;
  t.target_mm = {15.0, 0.0, 65.0};
  return t;
}

TEST(TruthFields, RoundTripToNineDigits) {
  std::map<std::string, std::string> f;
  SetTruthFields(Sample(), f);
  const std::optional<FrameGroundTruth> back = TruthFromFields(f);
  ASSERT_TRUE(back.has_value());
  EXPECT_TRUE(back->catheter_visible);
  EXPECT_FALSE(back->target_visible);
  EXPECT_LT((back->axis_point_mm - Sample().axis_point_mm).norm(), 1e-7);
  EXPECT_LT((back->axis_direction - Sample().axis_direction).norm(), 1e-8);
  EXPECT_LT((back->tip_mm - Sample().tip_mm).norm(), 1e-7);
  EXPECT_LT((back->target_mm - Sample().target_mm).norm(), 1e-7);
}

TEST(TruthFields, AbsentWithoutTheFlag) {
  EXPECT_FALSE(TruthFromFields({{"Timestamp", "1.0"}}).has_value());
}

TEST(TruthFields, BadValuesNameTheField) {
  std::map<std::string, std::string> f;
  SetTruthFields(Sample(), f);
  auto with = [&](const std::string& key, const std::string& value) {
    auto g = f;
    g[key] = value;
    return InvalidArgumentMessage([&] { TruthFromFields(g); });
  };
  ExpectContains(with("CatheterTip", "1 2"), "CatheterTip");
  ExpectContains(with("Target", "1 2 nan"), "Target");
  ExpectContains(with("CatheterAxisPoint", "1 2 3 4"), "CatheterAxisPoint");
  ExpectContains(with("CatheterVisible", "yes"), "CatheterVisible");
  ExpectContains(with("CatheterAxisDirection", "0 0 2"), "CatheterAxisDirection");
  auto g = f;
  g.erase("Target");
  ExpectContains(InvalidArgumentMessage([&] { TruthFromFields(g); }), "Target");
}

TEST(TruthFields, SimulatedRecordingCarriesItsTruth) {
  sim::SimulatedScannerOptions o;
  o.max_frames = 3;
  sim::SimulatedScanner scanner(o);
  std::vector<Volume> volumes;
  std::vector<FrameGroundTruth> truths;
  while (auto f = scanner.Next()) {
    ASSERT_TRUE(f->truth.has_value());
    truths.push_back(*f->truth);
    volumes.push_back(std::move(f->volume));
  }
  ASSERT_EQ(volumes.size(), 3u);
  PlusSequence seq = VolumesToSequence(volumes);
  for (std::size_t i = 0; i < truths.size(); ++i) SetTruthFields(truths[i], seq.frames[i].fields);
  const auto path = std::filesystem::temp_directory_path() /
                    ("echoservo_truth_" + std::to_string(::getpid()) + ".igs.mha");
  WritePlusSequence(seq, path, true);
  auto source = OpenRecording(path);
  for (std::size_t i = 0; i < truths.size(); ++i) {
    auto f = source->Next();
    ASSERT_TRUE(f.has_value());
    ASSERT_TRUE(f->truth.has_value());
    EXPECT_EQ(f->truth->catheter_visible, truths[i].catheter_visible);
    EXPECT_LT((f->truth->tip_mm - truths[i].tip_mm).norm(), 1e-6);
    EXPECT_LT((f->truth->target_mm - truths[i].target_mm).norm(), 1e-6);
    EXPECT_TRUE(std::equal(f->volume.voxels().begin(), f->volume.voxels().end(),
                           volumes[i].voxels().begin()));
  }
  EXPECT_FALSE(source->Next().has_value());
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace echoservo::imaging

// The STUDY folder files (tune/study_files.h), the paired statistics (tune/study_stats.h) and
// the study report (tune/study_report.h, `echoservo tune report`) on synthetic STUDY folders
// written with the study's own writers: objective values drawn around known differences from
// the default, so the report's best set, intervals and p-values are checked against ground
// truth and hand-counted sign patterns. About 1.6 s in Release, 1 s of it the CLI case
// starting the echoservo program three times.
#include "tune/study_report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "tests/test_util/browser.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/sanitizers.h"
#include "tests/test_util/temp_dir.h"
#include "tune/study_files.h"
#include "tune/study_stats.h"
#include "tune/trial.h"

namespace echoservo::tune {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using testing::InvalidArgumentMessage;
using testing::TempDir;

constexpr const char* kStandoff = "follower.standoff_mm";
constexpr const char* kWindow = "predictor.init_window_s";

void WriteText(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text;
}

// A STUDY folder written through the study's writers, one trial at a time.
class SyntheticStudy {
 public:
  SyntheticStudy(const fs::path& dir, int recordings, bool minimize = true) : dir_(dir) {
    header_.spec_json = R"({"search":{"method":"grid"}})";
    header_.spec_path = "/specs/sweep.json";
    header_.objective = minimize ? metric::kLoopRms : metric::kFoundFraction;
    header_.minimize = minimize;
    header_.search = "grid";
    header_.parameters = {kStandoff, kWindow};
    for (int r = 0; r < recordings; ++r) {
      header_.recordings.push_back("/data/rec" + std::to_string(r) + ".igs.mha");
      header_.recording_names.push_back("rec" + std::to_string(r));
      header_.em_logs.push_back("");
    }
    header_.created_utc = "2026-11-26T12:00:00Z";
    WriteStudyHeader(dir_, header_);
  }

  StudyTrial Request(int set, int rec, std::vector<live::Assignment> settings) const {
    StudyTrial t;
    t.id = TrialId(set, rec);
    t.set_index = set;
    t.recording_index = rec;
    t.request.recording = header_.recordings[static_cast<std::size_t>(rec)];
    t.request.settings = std::move(settings);
    t.request.latency_s = 0.08;
    t.request.from_s = 2.0;
    WriteTrialRequest(dir_, t);
    return t;
  }

  // A finished trial with objective `value` (NaN: a metric the trial could not compute).
  void Finished(int set, int rec, const std::vector<live::Assignment>& settings, double value) {
    const StudyTrial t = Request(set, rec, settings);
    TrialResult r;
    r.metrics[header_.objective] = value;
    r.metrics[metric::kLatencyP50] = 3.0;
    WriteTrialResult(dir_, t.id, r);
    WriteTaskOutcome(dir_, {t.id, 0, 0, false, 1.5, ""});
  }

  void Failed(int set, int rec, const std::vector<live::Assignment>& settings,
              const std::string& reason) {
    const StudyTrial t = Request(set, rec, settings);
    TrialResult r;
    r.status = "failed";
    r.reason = reason;
    WriteTrialResult(dir_, t.id, r);
    WriteTaskOutcome(dir_, {t.id, 2, 0, false, 0.4, ""});
  }

  const StudyHeader& header() const { return header_; }

 private:
  fs::path dir_;
  StudyHeader header_;
};

std::vector<live::Assignment> Settings(double standoff_mm, double window_s) {
  return {{kStandoff, standoff_mm}, {kWindow, window_s}};
}

Json ReportJson(const fs::path& study, StudyReportOptions o = {}) {
  return Json::parse(StudyReportJson(study, o));
}

const Json& SetJson(const Json& report, int set) {
  for (const Json& s : report["sets"])
    if (s["set"].get<int>() == set) return s;
  ADD_FAILURE() << "no set " << set;
  return report["sets"][0];
}

// ---- STUDY files ----

// One case per concern would start the test program once more each (CI time).
TEST(StudyFiles, IdsRoundTripAndMalformedFilesListedNotFatal) {
  {  // TrialIdsAreZeroPaddedAndOrdered
    EXPECT_EQ(TrialId(3, 1), "s0003-r01");
    EXPECT_EQ(TrialId(0, 0), "s0000-r00");
    EXPECT_EQ(TrialDir("/s", "s0003-r01"), fs::path("/s/trials/s0003-r01"));
    EXPECT_LT(TrialId(9, 99), TrialId(10, 0));
    EXPECT_NE(InvalidArgumentMessage([] { TrialId(-1, 0); }).find("negative"), std::string::npos);
    EXPECT_NE(InvalidArgumentMessage([] { TrialDir("/s", "../x"); }).find("not a trial id"),
              std::string::npos);
  }
  {  // EverythingWrittenReadsBackAndMalformedFilesAreListedNotFatal
    TempDir tmp("study_files", true);
    SyntheticStudy study(tmp.path(), 3);
    const StudyHeader h = ReadStudyHeader(tmp.path());
    EXPECT_EQ(h.spec_json, study.header().spec_json);  // byte for byte: a rerun compares it
    EXPECT_EQ(h.recordings, study.header().recordings);
    EXPECT_EQ(h.recording_names, study.header().recording_names);
    EXPECT_EQ(h.parameters, study.header().parameters);
    EXPECT_EQ(h.objective, metric::kLoopRms);
    EXPECT_TRUE(h.minimize);

    study.Finished(1, 0, Settings(6.0, 3.0), 1.25);
    // request.json is what `tune trial --request` reads: RequestFromJson takes it whole.
    const TrialRequest back = RequestFromJson(
        testing::ReadFile(TrialDir(tmp.path(), "s0001-r00") / "request.json"), "request.json");
    EXPECT_EQ(back.recording, "/data/rec0.igs.mha");
    EXPECT_EQ(back.settings, Settings(6.0, 3.0));
    study.Request(0, 2, {});  // not run yet
    // A timed-out trial: an outcome, no result.
    study.Request(2, 1, Settings(10.0, 2.0));
    WriteTaskOutcome(tmp.path(), {TrialId(2, 1), -1, 9, true, 600.0, ""});
    // A write killed before its rename leaves only the temporary: ignored.
    WriteText(TrialDir(tmp.path(), TrialId(2, 1)) / "result.json.tmp", "{\"status\": \"o");
    // Hand-edited files.
    study.Request(1, 1, Settings(6.0, 3.0));
    WriteText(TrialDir(tmp.path(), TrialId(1, 1)) / "result.json", "{\"status\": ");
    study.Finished(1, 2, Settings(6.0, 3.0), 1.5);
    WriteText(TrialDir(tmp.path(), TrialId(1, 2)) / "outcome.json", "[1, 2]");
    WriteText(TrialDir(tmp.path(), "s0009-r00") / "request.json", "{\"id\": 7}");

    std::vector<std::string> problems;
    const std::vector<StudyTrial> trials = ReadTrials(tmp.path(), &problems);
    ASSERT_EQ(trials.size(), 5u);
    EXPECT_EQ(trials[0].id, "s0000-r02");
    EXPECT_FALSE(trials[0].result.has_value());
    EXPECT_FALSE(trials[0].outcome.has_value());
    EXPECT_EQ(trials[1].id, "s0001-r00");
    ASSERT_TRUE(trials[1].result.has_value());
    EXPECT_EQ(trials[1].result->metrics.at(metric::kLoopRms), 1.25);
    ASSERT_EQ(trials[1].request.settings.size(), 2u);
    EXPECT_EQ(trials[1].request.settings[0], live::Assignment(kStandoff, 6.0));
    EXPECT_EQ(trials[1].request.latency_s, 0.08);
    ASSERT_TRUE(trials[1].outcome.has_value());
    EXPECT_EQ(trials[1].outcome->exit_code, 0);
    EXPECT_EQ(trials[1].outcome->wall_s, 1.5);
    EXPECT_EQ(trials[2].id, "s0001-r01");
    EXPECT_FALSE(trials[2].result.has_value());  // malformed: unfinished, so a rerun redoes it
    EXPECT_EQ(trials[3].id, "s0001-r02");
    EXPECT_TRUE(trials[3].result.has_value());    // its result stands ...
    EXPECT_FALSE(trials[3].outcome.has_value());  // ... its malformed outcome does not
    EXPECT_EQ(trials[4].id, "s0002-r01");
    ASSERT_TRUE(trials[4].outcome.has_value());
    EXPECT_TRUE(trials[4].outcome->timed_out);
    EXPECT_EQ(trials[4].outcome->signal, 9);
    EXPECT_FALSE(trials[4].result.has_value());
    ASSERT_EQ(problems.size(), 3u);
    std::string all;
    for (const std::string& p : problems) all += p + "\n";
    EXPECT_NE(all.find("s0001-r01"), std::string::npos) << all;
    EXPECT_NE(all.find("result.json"), std::string::npos) << all;
    EXPECT_NE(all.find("s0001-r02/outcome.json"), std::string::npos) << all;
    EXPECT_NE(all.find("s0009-r00/request.json"), std::string::npos) << all;

    // The outcome the Slurm job script writes by hand parses with the same fields.
    const TaskOutcome o = TaskOutcomeFromJson(
        R"({"id":"s0001-r00","exit_code":137,"signal":0,"timed_out":false,"wall_s":null,"error":""})",
        "job.sh");
    EXPECT_EQ(o.exit_code, 137);
    EXPECT_TRUE(std::isnan(o.wall_s));
    EXPECT_NE(InvalidArgumentMessage([] {
                TaskOutcomeFromJson(R"({"id":"x"})", "job.sh");
              }).find("job.sh: field 'exit_code' is missing"),
              std::string::npos);

    EXPECT_NE(InvalidArgumentMessage([&] {
                ReadStudyHeader(tmp.path() / "nope");
              }).find("no such STUDY folder"),
              std::string::npos);
    fs::create_directories(tmp.path() / "empty");
    EXPECT_NE(InvalidArgumentMessage([&] {
                ReadStudyHeader(tmp.path() / "empty");
              }).find("no study.json"),
              std::string::npos);
    WriteText(tmp.path() / "bad" / "study.json", R"({"format":"echoservo-study","version":1})");
    EXPECT_NE(InvalidArgumentMessage([&] {
                ReadStudyHeader(tmp.path() / "bad");
              }).find("study.json: field 'spec_json' is missing"),
              std::string::npos);
  }
}

// ---- statistics ----

// Hand-counted exact p-values, Monte Carlo against enumeration, n < 3.
TEST(StudyStats, ExactAndMonteCarloPValuesAndTheMinimumRecordings) {
  {  // SignFlipPValuesEqualHandCountedPatterns
    // {1, 2, 3, -0.5}: |sum| = 5.5; of the 16 sign patterns only ±(1+2+3+0.5) = ±6.5 and
    // ±5.5 reach it: p = 4/16.
    bool exact = false;
    EXPECT_DOUBLE_EQ(SignFlipPValue({1.0, 2.0, 3.0, -0.5}, 1000, 1, &exact), 4.0 / 16.0);
    EXPECT_TRUE(exact);
    // {-1, -2, -3, -4, 0.5}: |sum| = 9.5; reached by ±10.5 and ±9.5 only: 4/32.
    EXPECT_DOUBLE_EQ(SignFlipPValue({-1.0, -2.0, -3.0, -4.0, 0.5}, 1000, 1), 4.0 / 32.0);
    // Six equal differences: only all-plus and all-minus: 2/64.
    EXPECT_DOUBLE_EQ(SignFlipPValue(std::vector<double>(6, -0.3), 1000, 1), 2.0 / 64.0);
    // Ties by rounding count as ties: 0.1 + 0.2 against 0.3.
    EXPECT_DOUBLE_EQ(SignFlipPValue({0.1, 0.2, -0.3}, 1000, 1), 1.0);
  }
  {  // MonteCarloSignFlipAgreesWithFullEnumeration
    // n = 17 is above the exact limit: the Monte Carlo estimate against a brute-force count of
    // all 2^17 patterns, within 4 binomial standard errors.
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(-0.25, 1.0);
    std::vector<double> d(17);
    for (double& v : d) v = noise(rng);
    double observed = 0.0;
    for (double v : d) observed += v;
    std::size_t hits = 0;
    for (std::uint32_t mask = 0; mask < (1u << 17); ++mask) {
      double s = 0.0;
      for (std::size_t i = 0; i < 17; ++i) s += ((mask >> i) & 1u) != 0 ? -d[i] : d[i];
      if (std::abs(s) >= std::abs(observed) - 1e-12) ++hits;
    }
    const double truth = static_cast<double>(hits) / (1u << 17);
    bool exact = true;
    const int samples = 20000;
    const double p = SignFlipPValue(d, samples, 3, &exact);
    EXPECT_FALSE(exact);
    EXPECT_NEAR(p, truth, 4.0 * std::sqrt(truth * (1.0 - truth) / samples) + 1.0 / samples);
    EXPECT_GT(truth, 0.01);  // a case where the estimate has something to estimate
  }
  {  // FewerThanThreeRecordingsGiveNoIntervalOrTest
    const PairedComparison c = ComparePaired({-1.0, -1.2}, 2000, 0.95, 1);
    EXPECT_EQ(c.n, 2u);
    EXPECT_DOUBLE_EQ(c.mean_difference, -1.1);
    EXPECT_FALSE(c.meaningful);
    EXPECT_TRUE(std::isnan(c.ci_low));
    EXPECT_TRUE(std::isnan(c.p_value));
    EXPECT_THROW(BootstrapMeanCi({1.0}, 50, 0.95, 1), std::invalid_argument);
    EXPECT_THROW(BootstrapMeanCi({1.0}, 1000, 1.0, 1), std::invalid_argument);
  }
}

// ---- the report ----

// 8 recordings. Set 1 is better than the default by 0.5 mm (± 0.1 mm noise) on 7 of them
// and worse by 0.15 mm on rec7; set 2 changes nothing (± 0.2 mm); set 3 is better by 1 mm
// but failed on one recording; set 4 timed out on one and has a NaN metric on another;
// set 5 has a malformed result.json; set 6 was never run on rec0.
constexpr int kRecordings = 8;
constexpr double kSet1TrueMean = (7 * -0.5 + 0.15) / kRecordings;

void WriteMainStudy(const fs::path& dir) {
  SyntheticStudy study(dir, kRecordings);
  std::mt19937 rng(2026);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (int r = 0; r < kRecordings; ++r) {
    const double base = 1.2 + 0.3 * r;  // recordings differ far more than the sets
    study.Finished(0, r, {}, base);
    study.Finished(1, r, Settings(6.0, 3.0), base + (r == 7 ? 0.15 : -0.5 + 0.1 * n01(rng)));
    study.Finished(2, r, Settings(10.0, 3.0), base + 0.2 * n01(rng));
    if (r == 3) {
      study.Failed(3, r, Settings(4.0, 2.0), "detector: no catheter in 31 of 40 volumes");
    } else {
      study.Finished(3, r, Settings(4.0, 2.0), base - 1.0);
    }
    if (r == 5) {
      const StudyTrial t = study.Request(4, r, Settings(8.0, 4.0));
      WriteTaskOutcome(dir, {t.id, -1, 9, true, 600.0, ""});
    } else {
      study.Finished(4, r, Settings(8.0, 4.0), r == 6 ? std::nan("") : base + 0.1);
    }
    if (r == 2) {
      const StudyTrial t = study.Request(5, r, Settings(6.0, 2.0));
      WriteText(TrialDir(dir, t.id) / "result.json", "{not json");
    } else {
      study.Finished(5, r, Settings(6.0, 2.0), base + 0.3);
    }
    if (r == 0) {
      study.Request(6, r, Settings(10.0, 2.0));
    } else {
      study.Finished(6, r, Settings(10.0, 2.0), base + 0.05);
    }
  }
}

// The JSON and the HTML of one synthetic study (written once: about 0.2 s of fsyncs).
TEST(StudyReport, PicksTheBetterSetAndShowsItOnASelfContainedPage) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "0.5 s; the sanitizer suite runs the same report code in the two cases below");
  {  // PicksTheBetterSetAndCallsOnlyItBetterThanTheDefault
    TempDir tmp("study_report", true);
    WriteMainStudy(tmp.path());
    const Json j = ReportJson(tmp.path());

    ASSERT_FALSE(j["best"].is_null());
    EXPECT_EQ(j["best"]["set"], 1);  // set 3 has a lower mean but did not finish everywhere
    EXPECT_EQ(j["best"]["settings"][kStandoff], 6.0);
    EXPECT_EQ(j["best"]["settings"][kWindow], 3.0);
    const Json& v = j["best"]["vs_default"];
    EXPECT_EQ(v["n"], kRecordings);
    EXPECT_TRUE(v["meaningful"].get<bool>());
    EXPECT_TRUE(v["p_exact"].get<bool>());
    // The interval covers the true mean difference and excludes 0.
    EXPECT_LE(v["ci_low"].get<double>(), kSet1TrueMean);
    EXPECT_GE(v["ci_high"].get<double>(), kSet1TrueMean);
    EXPECT_LT(v["ci_high"].get<double>(), 0.0);
    // 7 of 8 differences near −0.5 and one of +0.15: only the patterns that flip the whole
    // set (2) or at most the +0.15 alone (2 more) reach the observed |sum|: p = 4/256.
    EXPECT_DOUBLE_EQ(v["p_value"].get<double>(), 4.0 / 256.0);
    EXPECT_TRUE(j["best"]["better_than_default"].get<bool>());
    EXPECT_NE(j["verdict"].get<std::string>().find("beats the default beyond noise"),
              std::string::npos);

    // Set 2 changes nothing: not better. Set 3 is not complete.
    EXPECT_FALSE(SetJson(j, 2)["better_than_default"].get<bool>());
    EXPECT_LE(SetJson(j, 2)["vs_default"]["ci_low"].get<double>(), 0.0);
    EXPECT_GE(SetJson(j, 2)["vs_default"]["ci_high"].get<double>(), 0.0);
    EXPECT_FALSE(SetJson(j, 3)["complete"].get<bool>());
    EXPECT_NEAR(SetJson(j, 3)["vs_default"]["mean_difference"].get<double>(), -1.0, 1e-9);
    EXPECT_TRUE(SetJson(j, 3)["per_recording"][3].is_null());
    EXPECT_EQ(j["sets"][0]["set"], 1);  // ranking: complete sets first, by mean

    // rec7 is the loser: the best set does worse there than the default.
    for (int r = 0; r < kRecordings; ++r)
      EXPECT_EQ(j["per_recording"][r]["best_worse_than_default"].get<bool>(), r == 7) << r;
    EXPECT_EQ(j["per_recording"][7]["own_best_set"], 3);  // set 3: −1 mm there

    // Failures with their reasons; the unrun trial is pending, not failed.
    EXPECT_EQ(j["trials"]["total"], 7 * kRecordings);
    EXPECT_EQ(j["trials"]["pending"], 1);
    EXPECT_EQ(j["trials"]["failed"], 4);
    std::map<std::string, std::string> reasons;
    for (const Json& f : j["failures"]) reasons[f["id"]] = f["reason"];
    EXPECT_NE(reasons["s0003-r03"].find("no catheter in 31 of 40"), std::string::npos);
    EXPECT_NE(reasons["s0004-r05"].find("timed out"), std::string::npos);
    EXPECT_NE(reasons["s0004-r06"].find("has no loop.tip_to_target_rms_mm"), std::string::npos);
    EXPECT_NE(reasons["s0005-r02"].find("result.json"), std::string::npos);
    ASSERT_EQ(j["problems"].size(), 1u);
    EXPECT_NE(j["problems"][0].get<std::string>().find("s0005-r02"), std::string::npos);

    // The commands replay the best set's settings on a recording of the study.
    ASSERT_GE(j["best"]["commands"].size(), 2u);
    const std::string trial = j["best"]["commands"][0];
    const std::string track = j["best"]["commands"][1];
    EXPECT_EQ(trial.rfind("echoservo tune trial --recording /data/rec0.igs.mha", 0), 0u) << trial;
    EXPECT_NE(trial.find("--set follower.standoff_mm=6 --set predictor.init_window_s=3"),
              std::string::npos)
        << trial;
    EXPECT_NE(trial.find("--latency 0.08"), std::string::npos) << trial;
    EXPECT_NE(trial.find("--from 2"), std::string::npos) << trial;
    EXPECT_EQ(track.rfind("echoservo track --replay /data/rec0.igs.mha --set", 0), 0u) << track;

    // The same seed gives the same figures; another seed moves the interval a little only.
    EXPECT_EQ(ReportJson(tmp.path()), j);
    StudyReportOptions other;
    other.seed = 99;
    const Json j2 = ReportJson(tmp.path(), other);
    EXPECT_NEAR(j2["best"]["vs_default"]["ci_low"].get<double>(), v["ci_low"].get<double>(), 0.05);
    EXPECT_EQ(j2["best"]["vs_default"]["p_value"], v["p_value"]);  // exact: no seed in it

    // The page of the same study.
    const std::string page = StudyReportHtml(tmp.path(), {});
    testing::browser::ExpectSelfContainedPage(page);
    // One plot per tuned parameter, each with a mark per finished trial.
    EXPECT_EQ(testing::browser::Count(page, "<svg"), 2u);
    EXPECT_NE(page.find("loop.tip_to_target_rms_mm against follower.standoff_mm"),
              std::string::npos);
    EXPECT_NE(page.find("loop.tip_to_target_rms_mm against predictor.init_window_s"),
              std::string::npos);
    EXPECT_EQ(testing::browser::Count(page, "<tr class=\"sig\">"), 1u);  // rec7, the loser
    EXPECT_NE(page.find("no catheter in 31 of 40 volumes"), std::string::npos);
    EXPECT_NE(page.find("Better than the default."), std::string::npos);
    EXPECT_NE(page.find("echoservo tune trial --recording /data/rec0.igs.mha"), std::string::npos);
    EXPECT_NE(page.find("echoservo track --replay /data/rec0.igs.mha"), std::string::npos);
    EXPECT_NE(page.find("sign-flip permutation test"), std::string::npos);
    EXPECT_NE(page.find("&quot;method&quot;: &quot;grid&quot;"), std::string::npos);  // the SPEC
    EXPECT_EQ(page.find(">nan"), std::string::npos);
    EXPECT_EQ(page.find(">-nan"), std::string::npos);
  }
}

// A large p with an interval clear of 0; two recordings only.
TEST(StudyReport, WeakEvidenceIsNeverCalledBetter) {
  {  // AnIntervalExcludingZeroWithALargePIsNotBetter
    // Five recordings, differences {−1, −2, −3, −4, +0.5}: nearly every resampled mean is
    // negative, but the exact test gives p = 4/32 = 0.125: not called better.
    TempDir tmp("study_report", true);
    SyntheticStudy study(tmp.path(), 5);
    const double d[] = {-1.0, -2.0, -3.0, -4.0, 0.5};
    for (int r = 0; r < 5; ++r) {
      study.Finished(0, r, {}, 10.0 + r);
      study.Finished(1, r, Settings(6.0, 3.0), 10.0 + r + d[r]);
    }
    const Json j = ReportJson(tmp.path());
    EXPECT_EQ(j["best"]["set"], 1);
    EXPECT_DOUBLE_EQ(j["best"]["vs_default"]["p_value"].get<double>(), 0.125);
    EXPECT_LT(j["best"]["vs_default"]["ci_high"].get<double>(), 0.0);
    EXPECT_FALSE(j["best"]["better_than_default"].get<bool>());
    EXPECT_NE(j["verdict"].get<std::string>().find("within noise"), std::string::npos);
    EXPECT_NE(StudyReportHtml(tmp.path(), {}).find("Not shown to be better."), std::string::npos);
  }
  {  // TwoRecordingsAreNotEnoughToCallASetBetter
    TempDir tmp("study_report", true);
    SyntheticStudy study(tmp.path(), 2, /*minimize=*/false);  // found fraction: higher is better
    study.Finished(0, 0, {}, 0.80);
    study.Finished(0, 1, {}, 0.70);
    study.Finished(1, 0, Settings(6.0, 3.0), 0.95);
    study.Finished(1, 1, Settings(6.0, 3.0), 0.90);
    study.Finished(2, 0, Settings(4.0, 3.0), 0.50);
    study.Finished(2, 1, Settings(4.0, 3.0), 0.60);
    const Json j = ReportJson(tmp.path());
    EXPECT_EQ(j["best"]["set"], 1);
    EXPECT_FALSE(j["best"]["vs_default"]["meaningful"].get<bool>());
    EXPECT_TRUE(j["best"]["vs_default"]["p_value"].is_null());
    EXPECT_TRUE(j["best"]["vs_default"]["ci_low"].is_null());
    EXPECT_NEAR(j["best"]["vs_default"]["mean_difference"].get<double>(), 0.175, 1e-12);
    EXPECT_FALSE(j["best"]["better_than_default"].get<bool>());
    EXPECT_NE(j["verdict"].get<std::string>().find("not shown to be better"), std::string::npos);
    const std::string page = StudyReportHtml(tmp.path(), {});
    EXPECT_NE(page.find("not meaningful (n &lt; 3)"), std::string::npos);
  }
}

TEST(StudyReport, BadStudiesAndOptionsAreNamedErrors) {
  TempDir tmp("study_report", true);
  EXPECT_NE(InvalidArgumentMessage([&] {
              StudyReportJson(tmp.path() / "missing", {});
            }).find("missing: no such STUDY folder"),
            std::string::npos);
  SyntheticStudy study(tmp.path(), 2);
  study.Failed(0, 0, {}, "recording unreadable");
  study.Request(0, 1, {});
  EXPECT_NE(
      InvalidArgumentMessage([&] { StudyReportHtml(tmp.path(), {}); })
          .find("no trial with a value of loop.tip_to_target_rms_mm yet (2 trials: 1 failed, 1 "
                "not run; s0000-r00: recording unreadable)"),
      std::string::npos);
  study.Finished(1, 0, Settings(6.0, 3.0), 1.0);
  StudyReportOptions o;
  o.bootstrap_samples = 10;
  EXPECT_NE(InvalidArgumentMessage([&] { StudyReportJson(tmp.path(), o); }).find("bootstrap"),
            std::string::npos);
  // No set finished everywhere: no best, and the page says so.
  const Json j = ReportJson(tmp.path());
  EXPECT_TRUE(j["best"].is_null());
  EXPECT_NE(StudyReportHtml(tmp.path(), {}).find("No best set."), std::string::npos);
}

TEST(StudyReportCli, MissingStudyIsAClearErrorAndJsonMatchesTheLibrary) {
  ECHOSERVO_REQUIRES_CLI();
  ECHOSERVO_RELEASE_SUITE_ONLY("starts the echoservo program three times (about 1.5 s)");
  TempDir tmp("study_report_cli", true);
  const testing::RunResult missing = testing::RunCli(
      "tune report " + (tmp.path() / "nope").string() + " --out x.html", tmp.path());
  EXPECT_NE(missing.rc, 0);
  EXPECT_NE(missing.err.find("nope: no such STUDY folder"), std::string::npos) << missing.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "x.html"));

  // A small study: 3 recordings, set 1 better than the default on each.
  const fs::path dir = tmp.path() / "study";
  SyntheticStudy study(dir, 3);
  for (int r = 0; r < 3; ++r) {
    study.Finished(0, r, {}, 2.0 + r);
    study.Finished(1, r, Settings(6.0, 3.0), 1.5 + r);
  }
  const testing::RunResult r = testing::RunCli("tune report " + dir.string() + " --json --out " +
                                               (tmp.path() / "s.html").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(Json::parse(r.out), ReportJson(dir));
  EXPECT_TRUE(fs::exists(tmp.path() / "s.html"));
  const testing::RunResult text = testing::RunCli("tune report " + dir.string());
  ASSERT_EQ(text.rc, 0) << text.err;
  EXPECT_NE(text.out.find("best set 1: follower.standoff_mm=6 predictor.init_window_s=3"),
            std::string::npos)
      << text.out;
  EXPECT_TRUE(fs::exists(dir / "report.html"));
}

}  // namespace
}  // namespace echoservo::tune

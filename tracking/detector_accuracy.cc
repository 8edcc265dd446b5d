#include "tracking/detector_accuracy.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <stdexcept>

#include "tracking/accuracy_volumes.h"

namespace echoservo::tracking {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
const char* const kMethods[] = {"fast", "tracking", "ransac", "exhaustive"};

// One method's raw figures over a set of volumes.
struct Sample {
  int volumes = 0, detected = 0;  // catheter volumes
  int free_volumes = 0, false_detections = 0;
  int errors = 0;
  std::vector<double> angle_deg, offset_mm, tip_mm, tip_along_mm, target_mm, detect_ms;
};

struct Timed {
  CatheterDetection d;
  double detect_ms = 0;
  bool error = false;
};

template <class F>
Timed Time(F&& detect) {
  Timed t;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    t.d = detect();
  } catch (const std::invalid_argument&) {
    t.error = true;
    t.d = CatheterDetection{};
  }
  t.detect_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return t;
}

struct Errors {
  double angle_deg = 0, offset_mm = 0, tip_mm = 0, tip_along_mm = 0, target_mm = 0;
  bool has_target = false;
};

Errors Measure(const CatheterDetection& d, const imaging::FrameGroundTruth& t) {
  Errors e;
  e.angle_deg = AngleBetweenLines(d.axis, Line3{t.axis_point_mm, t.axis_direction}) * 180.0 /
                std::numbers::pi;
  e.offset_mm = PointToLineDistance(d.axis, t.tip_mm);
  e.tip_mm = (d.tip_mm - t.tip_mm).norm();
  e.tip_along_mm = (d.tip_mm - t.tip_mm).dot(t.axis_direction.normalized());
  e.has_target = t.target_visible;
  e.target_mm = d.target_found ? (d.target_mm - t.target_mm).norm() : kInf;
  return e;
}

// Records one method's result on one volume in the class's and the pooled samples.
struct Recorder {
  std::map<std::string, Sample>& cls;
  std::map<std::string, Sample>& all;
  DetectorAccuracyReport& report;
  const VolumeClass& vc;
  int index;
  const std::string& label;

  void Add(const std::string& method, const Timed& t, const imaging::FrameGroundTruth* truth,
           bool axis_only) {
    VolumeRecord rec{vc.name, index, label, method,         t.d.found,  0,
                     0,       0,     0,     t.d.confidence, t.detect_ms};
    for (Sample* s : {&cls[method], &all[method]}) {
      s->detect_ms.push_back(t.detect_ms);
      s->errors += t.error ? 1 : 0;
      if (!vc.catheter) {
        ++s->free_volumes;
        s->false_detections += t.d.found ? 1 : 0;
        continue;
      }
      ++s->volumes;
      if (!t.d.found || truth == nullptr) continue;
      ++s->detected;
      const Errors e = Measure(t.d, *truth);
      s->angle_deg.push_back(e.angle_deg);
      s->offset_mm.push_back(e.offset_mm);
      rec.angle_deg = e.angle_deg;
      rec.offset_mm = e.offset_mm;
      if (axis_only) continue;
      s->tip_mm.push_back(e.tip_mm);
      s->tip_along_mm.push_back(e.tip_along_mm);
      rec.tip_mm = e.tip_mm;
      rec.tip_along_mm = e.tip_along_mm;
      if (e.has_target) {
        s->target_mm.push_back(e.target_mm);
        rec.target_mm = e.target_mm;
      }
    }
    report.records.push_back(rec);
  }
};

double Mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0.0 : s / static_cast<double>(v.size());
}

MethodStats Summarise(const std::string& method, const Sample& s) {
  MethodStats m;
  m.method = method;
  m.volumes = s.volumes + s.free_volumes;
  m.detected = s.detected + s.false_detections;
  m.errors = s.errors;
  m.detection_rate = s.volumes > 0 ? static_cast<double>(s.detected) / s.volumes : 0.0;
  m.angle_deg = ComputeQuantiles(s.angle_deg);
  m.offset_mm = ComputeQuantiles(s.offset_mm);
  m.tip_mm = ComputeQuantiles(s.tip_mm);
  m.tip_along_mm = ComputeQuantiles(s.tip_along_mm);
  m.target_mm = ComputeQuantiles(s.target_mm);
  m.false_detections = s.false_detections;
  m.mean_detect_ms = Mean(s.detect_ms);
  m.median_detect_ms = ComputeQuantiles(s.detect_ms).median;
  return m;
}

std::vector<MethodStats> SummariseAll(const std::map<std::string, Sample>& samples) {
  std::vector<MethodStats> out;
  for (const char* m : kMethods) {
    auto it = samples.find(m);
    if (it != samples.end()) out.push_back(Summarise(m, it->second));
  }
  return out;
}

struct Detectors {
  RadonDetector fast;
  RansacLineDetector ransac;
};

struct Agreement {
  std::vector<double> angle, offset;
};

void RunVolume(const VolumeClass& vc, const AccuracyVolume& av, const DetectorAccuracyOptions& o,
               const Detectors& det, Recorder& rec, Agreement& cls_agree, Agreement& all_agree) {
  const imaging::FrameGroundTruth* truth = av.truth ? &*av.truth : nullptr;
  const Timed fast = Time([&] { return det.fast.Detect(av.volume); });
  rec.Add("fast", fast, truth, false);
  if (o.tracking && vc.catheter && av.next_volume) {
    // Tracking as a live stream runs it: from the previous frame's detection (its axis and
    // scene statistics), so only the region around the axis is read.
    const Timed tr = Time([&] { return det.fast.Detect(*av.next_volume, fast.d); });
    rec.Add("tracking", tr, av.next_truth ? &*av.next_truth : nullptr, false);
  }
  if (o.ransac) rec.Add("ransac", Time([&] { return det.ransac.Detect(av.volume); }), truth, false);
  if (o.exhaustive && vc.catheter) {
    ExhaustiveRadonResult ex;
    const Timed t = Time([&] {
      ex = ExhaustiveRadonAxis(av.volume, o.exhaustive_options);
      CatheterDetection d;
      d.found = ex.found;
      d.axis = ex.axis;
      return d;
    });
    rec.Add("exhaustive", t, truth, true);
    if (ex.found && fast.d.found) {
      const AxisAgreement a = CompareAxes(fast.d.axis, fast.d.tip_mm, ex.axis);
      for (Agreement* g : {&cls_agree, &all_agree}) {
        g->angle.push_back(a.angle_deg);
        g->offset.push_back(a.offset_mm);
      }
    }
  }
}

}  // namespace

Quantiles ComputeQuantiles(std::vector<double> v) {
  Quantiles q;
  q.count = static_cast<int>(v.size());
  if (v.empty()) return q;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  q.median = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  const auto rank = static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(n)));
  q.p95 = v[std::clamp<std::size_t>(rank, 1, n) - 1];
  return q;
}

const MethodStats* ClassStats::Method(std::string_view method) const {
  for (const auto& m : methods)
    if (m.method == method) return &m;
  return nullptr;
}

void DetectorAccuracyOptions::Validate() const {
  if (volumes_per_class < 1 || volumes_per_class > 1000)
    throw std::invalid_argument("DetectorAccuracyOptions: volumes_per_class must be in [1, 1000]");
  for (const auto& c : classes) FindVolumeClass(c);
  fast.Validate();
  ransac_options.Validate();
  exhaustive_options.Validate();
}

DetectorAccuracyReport RunDetectorAccuracy(const DetectorAccuracyOptions& o) {
  o.Validate();
  DetectorAccuracyReport report;
  const Detectors det{RadonDetector(o.fast), RansacLineDetector(o.ransac_options)};
  std::map<std::string, Sample> all;
  Agreement all_agree;
  std::vector<VolumeClass> classes;
  if (o.classes.empty()) {
    classes = VolumeClasses();
  } else {
    for (const auto& c : o.classes) classes.push_back(FindVolumeClass(c));
  }
  for (const auto& vc : classes) {
    if (vc.real && o.spine_volume.empty()) {
      report.skipped.push_back(vc.name + ": no spine_volume file given");
      continue;
    }
    std::map<std::string, Sample> cls;
    Agreement cls_agree;
    const int n = vc.real ? 1 : o.volumes_per_class;
    int used = 0;
    for (int i = 0; i < n; ++i) {
      const AccuracyVolume av = MakeAccuracyVolume(vc, i, o.seed, o.tracking, o.spine_volume);
      if (vc.catheter && !(av.truth && av.truth->catheter_visible)) {
        report.skipped.push_back(vc.name + " #" + std::to_string(i) +
                                 ": catheter tip outside the view (" + av.label + ")");
        continue;
      }
      Recorder rec{cls, all, report, vc, i, av.label};
      const std::size_t first = report.records.size();
      RunVolume(vc, av, o, det, rec, cls_agree, all_agree);
      ++used;
      if (o.log) {
        std::string line = vc.name;
        line += " #";
        line += std::to_string(i);
        line += " (";
        line += av.label;
        line += "):";
        for (std::size_t r = first; r < report.records.size(); ++r) {
          const VolumeRecord& v = report.records[r];
          char buf[160];
          std::snprintf(buf, sizeof buf, " %s found %d angle %.3f tip %.3f target %.3f (%.1f ms);",
                        v.method.c_str(), v.found ? 1 : 0, v.angle_deg, v.tip_mm, v.target_mm,
                        v.detect_ms);
          line += buf;
        }
        o.log(line);
      }
    }
    ClassStats cs;
    cs.name = vc.name;
    cs.description = vc.description;
    cs.catheter = vc.catheter;
    cs.volumes = used;
    cs.methods = SummariseAll(cls);
    cs.agreement_angle_deg = ComputeQuantiles(cls_agree.angle);
    cs.agreement_offset_mm = ComputeQuantiles(cls_agree.offset);
    report.classes.push_back(cs);
  }
  report.overall = SummariseAll(all);
  report.agreement_angle_deg = ComputeQuantiles(all_agree.angle);
  report.agreement_offset_mm = ComputeQuantiles(all_agree.offset);
  return report;
}

}  // namespace echoservo::tracking

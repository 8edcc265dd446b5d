#include "tracking/temporal_calibration.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "imaging/io/em_log_import.h"

namespace echoservo::tracking {
namespace {

// Helpers carry a Tc prefix: the module is built as a unity source (one translation unit).
std::string TcNum(double v, int precision = 3) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(precision);
  s << v;
  return s.str();
}

std::string TcMs(double s) { return TcNum(1000.0 * s, 2) + " ms"; }

std::string TcFrameName(std::size_t i) { return "frame " + std::to_string(i); }

double TcPeakToPeak(std::span<const double> v) {
  if (v.empty()) return 0.0;
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return *hi - *lo;
}

// vtkPiecewiseFunction as PLUS builds it: linear between samples, the end values beyond them
// (Clamping on). Times strictly increasing. `hint` walks forward with increasing queries.
double TcClampedAt(const TimedSignal& s, double t, std::size_t* hint) {
  if (t <= s.t_s.front()) return s.value.front();
  if (t >= s.t_s.back()) return s.value.back();
  std::size_t i = *hint;
  if (i + 1 >= s.t_s.size() || s.t_s[i] > t) i = 0;
  while (s.t_s[i + 1] < t) ++i;
  *hint = i;
  const double w = (t - s.t_s[i]) / (s.t_s[i + 1] - s.t_s[i]);
  return (1.0 - w) * s.value[i] + w * s.value[i + 1];
}

// PLUS's NormalizeMetricValues: the mean and 1/SD (n − 1) over [start, stop], applied to all
// values; a SD below 1e-10 leaves the scale at 1. PLUS normalises its fixed signal in place
// at every offset; that equals normalising the original over the current window, done here.
std::vector<double> TcNormalized(std::span<const double> v, std::size_t start, std::size_t stop,
                                 double* factor = nullptr) {
  const double n = static_cast<double>(stop - start + 1);
  double mean = 0.0;
  for (std::size_t i = start; i <= stop; ++i) mean += v[i];
  mean /= n;
  double ss = 0.0;
  for (std::size_t i = start; i <= stop; ++i) ss += (v[i] - mean) * (v[i] - mean);
  const double sd = n > 1.0 ? std::sqrt(ss) / std::sqrt(n - 1.0) : 0.0;
  const double f = sd < 1e-10 ? 1.0 : 1.0 / sd;
  if (factor != nullptr) *factor = f;
  std::vector<double> out(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) out[i] = (v[i] - mean) * f;
  return out;
}

// The fixed samples PLUS normalises over at `offset`: from the first whose t ≥ t_0 + offset
// (else 0) to the last, searched down to index 1, whose t ≤ t_last + offset (else the last).
std::pair<std::size_t, std::size_t> TcFixedWindow(const std::vector<double>& t, double offset) {
  std::size_t start = 0;
  for (std::size_t i = 0; i < t.size(); ++i)
    if (t[i] >= t.front() + offset) {
      start = i;
      break;
    }
  std::size_t stop = t.size() - 1;
  for (std::size_t i = t.size() - 1; i != 0; --i)
    if (t[i] <= t.back() + offset) {
      stop = i;
      break;
    }
  return {start, stop};
}

struct TcPlusEval {
  double metric = 0.0;  // −SSD
  double moving_factor = 1.0;
};

// One offset of PLUS's ComputeCorrelationBetweenFixedAndMovingSignal (SSD metric).
TcPlusEval TcPlusMetricAt(const TimedSignal& fixed, const TimedSignal& moving, double offset) {
  const auto [start, stop] = TcFixedWindow(fixed.t_s, offset);
  const std::vector<double> f = TcNormalized(fixed.value, start, stop);
  std::vector<double> m(fixed.size());
  std::size_t hint = 0;
  for (std::size_t i = 0; i < fixed.size(); ++i)
    m[i] = TcClampedAt(moving, fixed.t_s[i] + offset, &hint);
  TcPlusEval e;
  const std::vector<double> mn = TcNormalized(m, 0, m.size() - 1, &e.moving_factor);
  double ssd = 0.0;
  for (std::size_t i = 0; i < f.size(); ++i) ssd += (f[i] - mn[i]) * (f[i] - mn[i]);
  e.metric = -ssd;
  return e;
}

struct TcPlusScan {
  double best_offset = 0.0;
  TcPlusEval best;
  double last_offset = 0.0;  // PLUS's fixed signal stays normalised for this one
  LagCurve curve;
};

// PLUS's scan: offsets from `from`, adding `step` while ≤ `to` (accumulated, as PLUS does);
// the first strictly best metric wins.
TcPlusScan TcPlusScanRange(const TimedSignal& fixed, const TimedSignal& moving, double from,
                           double to, double step) {
  TcPlusScan s;
  bool first = true;
  for (double offset = from; offset <= to; offset += step) {
    const TcPlusEval e = TcPlusMetricAt(fixed, moving, offset);
    s.curve.lag_s.push_back(offset);
    s.curve.value.push_back(e.metric);
    s.last_offset = offset;
    if (first || e.metric > s.best.metric) {
      s.best = e;
      s.best_offset = offset;
      first = false;
    }
  }
  return s;
}

// Pearson r of fixed[first..last] and the moving signal at t + lag (times inside its span).
double TcPearsonAt(const TimedSignal& fixed, std::size_t first, std::size_t last,
                   const TimedSignal& moving, double lag) {
  double sf = 0, sm = 0, sff = 0, smm = 0, sfm = 0;
  std::size_t hint = 0;
  const double n = static_cast<double>(last - first + 1);
  for (std::size_t i = first; i <= last; ++i) {
    const double f = fixed.value[i];
    const double m = TcClampedAt(moving, fixed.t_s[i] + lag, &hint);
    sf += f;
    sm += m;
    sff += f * f;
    smm += m * m;
    sfm += f * m;
  }
  const double cov = sfm - sf * sm / n;
  const double vf = sff - sf * sf / n, vm = smm - sm * sm / n;
  if (!(vf > 0.0) || !(vm > 0.0)) return 0.0;
  return cov / std::sqrt(vf * vm);
}

// The confidence figures from the r curve of the chosen polarity.
LagConfidence TcConfidence(const TimedSignal& fixed, std::size_t first, std::size_t last,
                           const TimedSignal& moving, double plus_lag, double coarse_step,
                           const LagOptions& o) {
  LagConfidence c;
  c.samples = last - first + 1;
  const auto steps = static_cast<long>(std::llround(2.0 * o.max_lag_s / o.resolution_s));
  for (long k = 0; k <= steps; ++k) {
    const double lag = -o.max_lag_s + static_cast<double>(k) * o.resolution_s;
    c.curve.lag_s.push_back(lag);
    c.curve.value.push_back(TcPearsonAt(fixed, first, last, moving, lag));
  }
  const std::vector<double>& r = c.curve.value;
  const std::size_t n = r.size();
  // The peak: the highest r within ±3 coarse steps of PLUS's lag.
  std::size_t peak = 0;
  bool found = false;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::abs(c.curve.lag_s[i] - plus_lag) > 3.0 * coarse_step) continue;
    if (!found || r[i] > r[peak]) peak = i, found = true;
  }
  c.peak_r = r[peak];
  c.peak_lag_s = c.curve.lag_s[peak];
  // κ from a least-squares parabola over ±10 ms (at least ±2 samples).
  const long half = std::max<long>(2, std::lround(0.01 / o.resolution_s));
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  for (long d = -half; d <= half; ++d) {
    const long i = static_cast<long>(peak) + d;
    if (i < 0 || i >= static_cast<long>(n)) continue;
    const double x = static_cast<double>(d) * o.resolution_s;
    const Eigen::Vector3d a(x * x, x, 1.0);
    ata += a * a.transpose();
    atb += a * r[static_cast<std::size_t>(i)];
  }
  const Eigen::Vector3d quad = ata.ldlt().solve(atb);  // r ≈ q0 x² + q1 x + q2
  const double kappa = -2.0 * quad(0);
  // The vertex, when the parabola opens down and its vertex lies within the fitted span.
  if (kappa > 0.0 && std::abs(quad(1) / kappa) <= static_cast<double>(half) * o.resolution_s)
    c.peak_lag_s += quad(1) / kappa;
  c.lag_sd_s = kappa > 0.0 && c.peak_r > 0.0
                   ? std::sqrt(std::max(0.0, 1.0 - c.peak_r * c.peak_r) /
                               (c.peak_r * static_cast<double>(c.samples) * kappa))
                   : std::numeric_limits<double>::infinity();
  // Widths: misfit within a factor 2 of the peak's; half height above the floor.
  const auto width_where = [&](auto inside) {
    std::size_t lo = peak, hi = peak;
    while (lo > 0 && inside(r[lo - 1])) --lo;
    while (hi + 1 < n && inside(r[hi + 1])) ++hi;
    return std::pair<std::size_t, std::size_t>{lo, hi};
  };
  const double misfit = 1.0 - c.peak_r;
  const auto [mlo, mhi] = width_where([&](double v) { return 1.0 - v <= 2.0 * misfit; });
  c.misfit_width_s = c.curve.lag_s[mhi] - c.curve.lag_s[mlo];
  const double floor = *std::min_element(r.begin(), r.end());
  const double half_height = floor + 0.5 * (c.peak_r - floor);
  const auto [flo, fhi] = width_where([&](double v) { return v >= half_height; });
  c.fwhm_s = c.curve.lag_s[fhi] - c.curve.lag_s[flo];
  // The best other local maximum, outside the peak's half-height lobe.
  for (std::size_t i = 1; i + 1 < n; ++i) {
    if (i >= flo && i <= fhi) continue;
    if (!(r[i] >= r[i - 1] && r[i] > r[i + 1])) continue;
    if (std::isnan(c.second_r) || r[i] > c.second_r) {
      c.second_r = r[i];
      c.second_lag_s = c.curve.lag_s[i];
    }
  }
  // The other polarity: the negated tracker's r is −r.
  const auto lowest = std::min_element(r.begin(), r.end());
  c.other_polarity_r = -*lowest;
  c.other_polarity_lag_s = c.curve.lag_s[static_cast<std::size_t>(lowest - r.begin())];
  return c;
}

// The inverse of a rigid 4×4 (rotation + translation).
Eigen::Matrix4d TcRigidInverse(const Eigen::Matrix4d& m) {
  Eigen::Matrix4d inv = Eigen::Matrix4d::Identity();
  inv.block<3, 3>(0, 0) = m.block<3, 3>(0, 0).transpose();
  inv.block<3, 1>(0, 3) = -m.block<3, 3>(0, 0).transpose() * m.block<3, 1>(0, 3);
  return inv;
}

}  // namespace

VideoSignal ReflectorSignal(std::span<const VideoFrame> frames, const std::string& source,
                            const ReflectorLineOptions& line) {
  VideoSignal s;
  s.frames = frames.size();
  if (frames.size() < 2)
    throw std::invalid_argument(source + ": " + std::to_string(frames.size()) +
                                " video frame(s); temporal calibration needs a sweep");
  s.width = frames.front().width;
  s.height = frames.front().height;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const VideoFrame& f = frames[i];
    if (f.width != s.width || f.height != s.height) {
      throw std::invalid_argument(
          source + ": " + TcFrameName(i) + " is " + std::to_string(f.width) + " x " +
          std::to_string(f.height) + " pixels, frame 0 " + std::to_string(s.width) + " x " +
          std::to_string(s.height) + ": video frames of different sizes cannot be compared");
    }
    if (s.width < 1 || s.height < 1 ||
        f.pixels.size() != static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height))
      throw std::invalid_argument(source + ": " + TcFrameName(i) + " has " +
                                  std::to_string(f.pixels.size()) + " pixels, not " +
                                  std::to_string(s.width) + " x " + std::to_string(s.height));
  }
  try {
    s.region = FitClipToFrame(line.clip, s.width, s.height);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(source + ": " + e.what());
  }
  s.first_frame_t_s = frames.front().t_s;
  s.last_frame_t_s = frames.back().t_s;
  // Not PLUS's: the static background (the per-pixel median of up to 31 frames spread over
  // the sweep: ring-down, housing reverberations, overlays), removed when asked.
  const std::size_t n_px = frames.front().pixels.size();
  std::vector<std::uint8_t> background(n_px, 0);
  s.background_subtracted = line.subtract_static_background && frames.size() >= 8;
  if (s.background_subtracted) {
    const std::size_t k = std::min<std::size_t>(31, frames.size());
    std::vector<std::uint8_t> values(k);
    for (std::size_t p = 0; p < n_px; ++p) {
      for (std::size_t j = 0; j < k; ++j)
        values[j] = frames[j * (frames.size() - 1) / (k - 1)].pixels[p];
      std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k / 2),
                       values.end());
      background[p] = values[k / 2];
    }
  }
  std::vector<std::uint8_t> moving(n_px);
  double previous = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const VideoFrame& f = frames[i];
    if (!std::isfinite(f.t_s))
      throw std::invalid_argument(source + ": " + TcFrameName(i) + " has no finite timestamp");
    if (f.t_s < previous) {
      throw std::invalid_argument(source + ": " + TcFrameName(i) + " timestamp " + TcNum(f.t_s, 6) +
                                  " s is before the previous frame's " + TcNum(previous, 6) + " s");
    }
    if (f.t_s == previous) ++s.duplicates;  // PLUS keeps both
    previous = f.t_s;
    std::span<const std::uint8_t> px = f.pixels;
    if (s.background_subtracted) {
      for (std::size_t p = 0; p < n_px; ++p)
        moving[p] = f.pixels[p] > background[p]
                        ? static_cast<std::uint8_t>(f.pixels[p] - background[p])
                        : std::uint8_t{0};
      px = moving;
    }
    const std::optional<ReflectorLine> found = FindReflectorLine(px, f.width, f.height, line);
    if (!found) {
      ++s.no_line;
      continue;
    }
    s.depth_px.t_s.push_back(f.t_s);
    s.depth_px.value.push_back(found->depth_px);
  }
  return s;
}

VideoSignal ReflectorSignal(const imaging::PlusSequence& video, const std::string& source,
                            const ReflectorLineOptions& line) {
  if (video.FrameBytes() == 0)
    throw std::invalid_argument(
        source + ": no image data (DimSize " + std::to_string(video.frame_dims[0]) + " " +
        std::to_string(video.frame_dims[1]) + "): a tracker-only sequence, not a video");
  if (video.element_type != "MET_UCHAR")
    throw std::invalid_argument(source + ": ElementType " + video.element_type +
                                "; temporal calibration reads 8-bit (MET_UCHAR) frames");
  const int nx = video.frame_dims[0], ny = video.frame_dims[1], nz = video.frame_dims[2];
  const bool thin_volume = video.volume_frames && nz > 1;
  const int width = nx;
  const int height = thin_volume ? nz : ny;
  if (width < 2 || height < 2)
    throw std::invalid_argument(source + ": frames of " + std::to_string(width) + " x " +
                                std::to_string(height) +
                                " pixels (lateral x depth); a reflector line needs at least 2 x 2");
  const std::string size_text = std::to_string(nx) + " " + std::to_string(ny) +
                                (video.volume_frames ? " " + std::to_string(nz) : "");
  std::vector<std::vector<std::uint8_t>> slices;
  std::vector<VideoFrame> frames;
  std::size_t invalid = 0;
  for (std::size_t i = 0; i < video.frames.size(); ++i) {
    const imaging::SequenceFrame& f = video.frames[i];
    if (const auto size = f.Field("FrameSize")) {
      std::istringstream in(*size);
      std::vector<int> dims;
      for (int d; in >> d;) dims.push_back(d);
      std::vector<int> expected = {nx, ny};
      if (video.volume_frames) expected.push_back(nz);
      if (dims != expected) {
        throw std::invalid_argument(source + ": " + TcFrameName(i) + " FrameSize '" + *size +
                                    "' differs from the sequence's DimSize " + size_text +
                                    ": video frames of different sizes cannot be compared");
      }
    }
    const auto status = f.ImageStatus();
    if (status && *status != "OK") {
      ++invalid;
      continue;
    }
    const auto t = f.Timestamp();
    if (!t) throw std::invalid_argument(source + ": " + TcFrameName(i) + " has no Timestamp");
    VideoFrame v;
    v.t_s = *t;
    v.width = width;
    v.height = height;
    const std::span<const std::uint8_t> px = video.FramePixels(i);
    if (thin_volume) {
      // The middle y slice: an X × Z image, z (depth) as its rows.
      std::vector<std::uint8_t> slice(static_cast<std::size_t>(nx) * static_cast<std::size_t>(nz));
      const std::size_t y = static_cast<std::size_t>(ny / 2);
      for (std::size_t z = 0; z < static_cast<std::size_t>(nz); ++z)
        for (std::size_t x = 0; x < static_cast<std::size_t>(nx); ++x)
          slice[z * static_cast<std::size_t>(nx) + x] =
              px[(z * static_cast<std::size_t>(ny) + y) * static_cast<std::size_t>(nx) + x];
      slices.push_back(std::move(slice));
    } else {
      v.pixels = px.first(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny));
    }
    frames.push_back(v);
  }
  if (thin_volume)
    for (std::size_t i = 0; i < frames.size(); ++i) frames[i].pixels = slices[i];
  VideoSignal s = ReflectorSignal(frames, source, line);
  s.frames = video.frames.size();
  s.invalid = invalid;
  // PLUS's common range counts every frame of the list, valid or not.
  if (const auto t0 = video.frames.front().Timestamp()) s.first_frame_t_s = *t0;
  if (const auto t1 = video.frames.back().Timestamp()) s.last_frame_t_s = *t1;
  const double lateral = video.spacing_mm[0];
  const double depth = thin_volume ? video.spacing_mm[2] : video.spacing_mm[1];
  s.spacing_known = !(lateral == 1.0 && depth == 1.0);
  s.spacing_mm = depth;
  return s;
}

TrackerPoses ReadProbePoses(const imaging::PlusSequence& tracker, const std::string& tool,
                            const std::string& source) {
  const std::vector<std::string> tools = imaging::PlusTrackerTools(tracker);
  const auto has = [&](const std::string& t) {
    return std::find(tools.begin(), tools.end(), t) != tools.end();
  };
  const auto list = [&] {
    std::string text;
    for (const std::string& t : tools) text += (text.empty() ? "" : ", ") + t;
    return text.empty() ? std::string("none") : text;
  };
  std::string name = tool;
  const std::string suffix = "Transform";
  if (name.size() > suffix.size() &&
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
    name.resize(name.size() - suffix.size());
  // "AToB" absent: inverse(BToC) · AToC for a C that both reach (PLUS's repository).
  std::string via_from, via_to;
  if (name.empty()) {
    if (has("ProbeToTracker"))
      name = "ProbeToTracker";
    else if (tools.size() == 1)
      name = tools.front();
    else
      throw std::invalid_argument(source +
                                  ": no ProbeToTracker transform; name the probe's tool "
                                  "with --tool (tools in the file: " +
                                  list() + ")");
  } else if (!has(name)) {
    const auto to = name.find("To");
    if (to != std::string::npos && to > 0 && to + 2 < name.size()) {
      const std::string a = name.substr(0, to), b = name.substr(to + 2);
      for (const std::string& t : tools) {
        if (t.rfind(a + "To", 0) != 0) continue;
        const std::string c = t.substr(a.size() + 2);
        if (has(b + "To" + c)) {
          via_from = t;
          via_to = b + "To" + c;
          break;
        }
      }
    }
    if (via_from.empty())
      throw std::invalid_argument(source + ": no tool " + name +
                                  " in the file, nor two tools to compose it from (tools in the "
                                  "file: " +
                                  list() + ")");
  }
  TrackerPoses s;
  s.tool = name;
  s.frames = tracker.frames.size();
  if (!tracker.frames.empty()) {
    if (const auto t0 = tracker.frames.front().Timestamp()) s.first_frame_t_s = *t0;
    if (const auto t1 = tracker.frames.back().Timestamp()) s.last_frame_t_s = *t1;
  }
  for (std::size_t i = 0; i < tracker.frames.size(); ++i) {
    const imaging::SequenceFrame& f = tracker.frames[i];
    Eigen::Matrix4d m;
    if (via_from.empty()) {
      if (!f.TransformValid(name)) {
        ++s.not_ok[f.TransformStatus(name).value_or("absent")];
        continue;
      }
      m = *f.Transform(name);
    } else {
      if (!f.TransformValid(via_from) || !f.TransformValid(via_to)) {
        const std::string bad = f.TransformValid(via_from) ? via_to : via_from;
        ++s.not_ok[bad + " " + f.TransformStatus(bad).value_or("absent")];
        continue;
      }
      m = TcRigidInverse(*f.Transform(via_to)) * *f.Transform(via_from);
    }
    const auto time = f.Timestamp();
    if (!time) throw std::invalid_argument(source + ": " + TcFrameName(i) + " has no Timestamp");
    if (!s.t_s.empty() && *time <= s.t_s.back()) {
      if (*time == s.t_s.back()) {
        // vtkPiecewiseFunction replaces a point at the same time: the later pose stays.
        ++s.duplicates;
        s.position_mm.back() = m.block<3, 1>(0, 3);
        continue;
      }
      throw std::invalid_argument(source + ": " + TcFrameName(i) + " timestamp " + TcNum(*time, 6) +
                                  " s is before the previous frame's " + TcNum(s.t_s.back(), 6) +
                                  " s");
    }
    s.t_s.push_back(*time);
    s.position_mm.push_back(m.block<3, 1>(0, 3));
  }
  if (s.t_s.size() < 2) {
    std::string statuses;
    for (const auto& [status, n] : s.not_ok)
      statuses += (statuses.empty() ? "" : ", ") + status + " " + std::to_string(n);
    throw std::invalid_argument(source + ": tool " + name + " has " + std::to_string(s.t_s.size()) +
                                " OK transform(s) in " + std::to_string(s.frames) + " frames (" +
                                (statuses.empty() ? "none" : statuses) +
                                "): no probe motion to calibrate with");
  }
  return s;
}

PrincipalMotion ProjectOnPrincipalMotion(const TrackerPoses& poses, double from_s, double to_s,
                                         const std::string& source) {
  std::vector<std::size_t> used;
  for (std::size_t i = 0; i < poses.t_s.size(); ++i)
    if (poses.t_s[i] >= from_s && poses.t_s[i] <= to_s) used.push_back(i);
  if (used.size() < 2)
    throw std::invalid_argument(source + ": " + std::to_string(used.size()) + " " + poses.tool +
                                " pose(s) between " + TcNum(from_s, 3) + " and " + TcNum(to_s, 3) +
                                " s; the principal motion needs 2");
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const std::size_t i : used) mean += poses.position_mm[i];
  mean /= static_cast<double>(used.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const std::size_t i : used)
    cov += (poses.position_mm[i] - mean) * (poses.position_mm[i] - mean).transpose();
  cov /= static_cast<double>(used.size() - 1);  // vtkPCAStatistics: sample covariance
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  PrincipalMotion m;
  m.axis = eig.eigenvectors().col(2);  // eigenvalues ascending
  Eigen::Index largest = 0;
  m.axis.cwiseAbs().maxCoeff(&largest);
  if (m.axis[largest] < 0.0) m.axis = -m.axis;
  m.spread_mm = eig.eigenvalues().reverse().cwiseMax(0.0).cwiseSqrt();
  for (const std::size_t i : used) {
    m.position_mm.t_s.push_back(poses.t_s[i]);
    m.position_mm.value.push_back(poses.position_mm[i].dot(m.axis));  // PLUS: not centred
  }
  return m;
}

LagResult EstimateTrackerLag(const VideoSignal& video, const TrackerPoses& tracker,
                             const LagOptions& o, const std::string& video_source,
                             const std::string& tracker_source) {
  if (!(o.max_lag_s > 0.0) || !(o.resolution_s >= 1e-4) || o.resolution_s > o.max_lag_s ||
      !(o.min_tracker_p2p_mm >= 0.0) || !(o.min_video_p2p_px >= 0.0) || o.min_samples < 3 ||
      !(o.max_plus_ssd > 0.0) || !(o.min_peak_r >= -1.0 && o.min_peak_r <= 1.0) ||
      !(o.max_lag_sd_s > 0.0) || !(o.similar_misfit_ratio >= 1.0)) {
    throw std::invalid_argument(
        "temporal calibration: options out of range (max_lag_s > 0, resolution_s in [1e-4, "
        "max_lag_s] (PLUS's TIMESTAMP_EPSILON_SEC), peak-to-peak limits >= 0, min_samples >= "
        "3, max_plus_ssd > 0, min_peak_r in [-1, 1], max_lag_sd_s > 0, similar_misfit_ratio "
        ">= 1)");
  }
  const std::string both = video_source + " and " + tracker_source;
  LagResult r;
  // Stage 1 (ComputeCommonTimeRange): both files' first and last frames, any status.
  r.common_from_s = std::max(video.first_frame_t_s, tracker.first_frame_t_s);
  r.common_to_s = std::min(video.last_frame_t_s, tracker.last_frame_t_s);
  r.moving_from_s = r.common_from_s + o.max_lag_s;
  r.moving_to_s = r.common_to_s - o.max_lag_s;
  if (!(r.moving_from_s < r.moving_to_s)) {
    throw std::invalid_argument(
        both + ": the recordings overlap " + TcNum(r.common_from_s, 3) + " … " +
        TcNum(r.common_to_s, 3) + " s (video " + TcNum(video.first_frame_t_s, 3) + " … " +
        TcNum(video.last_frame_t_s, 3) + " s, tracker " + TcNum(tracker.first_frame_t_s, 3) +
        " … " + TcNum(tracker.last_frame_t_s, 3) + " s): less than twice the max lag " +
        TcNum(o.max_lag_s, 3) + " s; record both together for longer, or lower --max-lag");
  }
  // Stage 2 (ComputePositionSignalValues): the fixed signal in the common range, the moving
  // one in the common range less max_lag at each end.
  TimedSignal fixed;
  for (std::size_t i = 0; i < video.depth_px.size(); ++i) {
    if (video.depth_px.t_s[i] < r.common_from_s || video.depth_px.t_s[i] > r.common_to_s) continue;
    fixed.t_s.push_back(video.depth_px.t_s[i]);
    fixed.value.push_back(video.depth_px.value[i]);
  }
  if (fixed.size() < 2)
    throw std::invalid_argument(video_source + ": " + std::to_string(fixed.size()) +
                                " frame(s) with a reflector line in the recordings' common "
                                "range; a water-tank bottom sweep is needed");
  const PrincipalMotion motion =
      ProjectOnPrincipalMotion(tracker, r.moving_from_s, r.moving_to_s, tracker_source);
  const TimedSignal& moving_plus = motion.position_mm;
  r.axis = motion.axis;
  r.video_samples_used = fixed.size();
  r.tracker_samples_used = moving_plus.size();
  r.tracker_p2p_mm = TcPeakToPeak(moving_plus.value);
  r.video_p2p_px = TcPeakToPeak(fixed.value);
  if (r.tracker_p2p_mm < o.min_tracker_p2p_mm) {
    throw std::invalid_argument(tracker_source + ": the probe moves " + TcNum(r.tracker_p2p_mm, 2) +
                                " mm peak-to-peak along its principal direction over the "
                                "poses used; temporal calibration needs at least " +
                                TcNum(o.min_tracker_p2p_mm, 1) +
                                " mm (not enough motion to correlate)");
  }
  if (r.video_p2p_px < o.min_video_p2p_px) {
    throw std::invalid_argument(video_source + ": the reflector moves " + TcNum(r.video_p2p_px, 1) +
                                " pixels peak-to-peak in the frames used; temporal calibration "
                                "needs at least " +
                                TcNum(o.min_video_p2p_px, 1) + " (not enough motion to correlate)");
  }
  // Stage 3: the coarse step is the mean video frame period of the frames used.
  r.coarse_step_s = (fixed.t_s.back() - fixed.t_s.front()) / static_cast<double>(fixed.size() - 1);
  if (r.coarse_step_s < 1e-4)
    throw std::invalid_argument(video_source + ": video frame period " + TcNum(r.coarse_step_s, 6) +
                                " s; PLUS's coarse scan needs at least 0.0001 s");
  // Stage 4: coarse then fine scan, each polarity (the tracker negated for the second).
  TimedSignal negated = moving_plus;
  for (double& v : negated.value) v = -v;
  TcPlusScan coarse[2], fine[2];
  for (int p = 0; p < 2; ++p) {
    const TimedSignal& moving = p == 0 ? moving_plus : negated;
    coarse[p] = TcPlusScanRange(fixed, moving, -o.max_lag_s, o.max_lag_s, r.coarse_step_s);
    fine[p] = TcPlusScanRange(fixed, moving, coarse[p].best_offset - 3.0 * r.coarse_step_s,
                              coarse[p].best_offset + 3.0 * r.coarse_step_s, o.resolution_s);
  }
  // Stage 5: PLUS adopts the smaller |lag| (ties: the negated tracker).
  const int chosen = std::abs(fine[0].best_offset) < std::abs(fine[1].best_offset) ? 0 : 1;
  const TimedSignal& moving = chosen == 0 ? moving_plus : negated;
  r.inverted = chosen == 1;
  r.tracker_lag_s = fine[chosen].best_offset;
  r.other_lag_s = fine[1 - chosen].best_offset;
  r.coarse_lag_s = coarse[chosen].best_offset;
  r.coarse = coarse[chosen].curve;
  r.fine = fine[chosen].curve;
  r.plus_ssd = -fine[chosen].best.metric;
  const double factor = fine[chosen].best.moving_factor;
  r.plus_calibration_error = std::sqrt(r.plus_ssd) / factor;
  {
    // MaxCalibrationError: the tracker normalised over its samples inside the shifted video
    // span, against the video as PLUS leaves it (normalised for the last offset it tried).
    TimedSignal window;
    for (std::size_t k = 0; k < moving.size(); ++k) {
      if (moving.t_s[k] > fixed.t_s.front() + r.tracker_lag_s &&
          moving.t_s[k] < fixed.t_s.back() + r.tracker_lag_s) {
        window.t_s.push_back(moving.t_s[k]);
        window.value.push_back(moving.value[k]);
      }
    }
    r.plus_max_calibration_error = std::numeric_limits<double>::quiet_NaN();
    if (window.size() >= 2) {
      window.value = TcNormalized(window.value, 0, window.size() - 1);
      const auto [start, stop] = TcFixedWindow(fixed.t_s, fine[1].last_offset);
      const std::vector<double> f = TcNormalized(fixed.value, start, stop);
      double worst = 0.0;
      std::size_t hint = 0;
      for (std::size_t i = 0; i < fixed.size(); ++i) {
        const double d = TcClampedAt(window, fixed.t_s[i] + r.tracker_lag_s, &hint) - f[i];
        worst = std::max(worst, d * d);
      }
      r.plus_max_calibration_error = std::sqrt(worst) / factor;
    }
  }
  // PLUS's own refusal: a best metric at or below its threshold.
  if (r.plus_ssd >= o.max_plus_ssd) {
    throw std::invalid_argument(both + ": the best alignment (lag " + TcMs(r.tracker_lag_s) +
                                ") leaves a sum of squared differences of " + TcNum(r.plus_ssd, 1) +
                                " between the normalised signals, at "
                                "or above PLUS's limit " +
                                TcNum(o.max_plus_ssd, 0) + ": the signals do not match");
  }
  if (std::abs(r.tracker_lag_s) > o.max_lag_s - r.coarse_step_s) {
    throw std::invalid_argument(both + ": the best lag " + TcNum(r.tracker_lag_s, 4) +
                                " s lies at the edge of the search window ±" +
                                TcNum(o.max_lag_s, 3) +
                                " s; the true lag may lie beyond it (raise --max-lag)");
  }
  // Confidence, over the frames every trial lag compares without reading the tracker's ends.
  std::size_t first = fixed.size(), last = 0;
  for (std::size_t i = 0; i < fixed.size(); ++i) {
    if (fixed.t_s[i] - o.max_lag_s < moving.t_s.front() ||
        fixed.t_s[i] + o.max_lag_s > moving.t_s.back())
      continue;
    first = std::min(first, i);
    last = i;
  }
  const std::size_t count = first <= last ? last - first + 1 : 0;
  if (count < o.min_samples) {
    throw std::invalid_argument(
        both + ": " + std::to_string(count) + " video frames lie at least twice the max lag " +
        TcNum(o.max_lag_s, 3) + " s inside the common range " + TcNum(r.common_from_s, 3) + " … " +
        TcNum(r.common_to_s, 3) + " s; " + std::to_string(o.min_samples) +
        " are needed to judge the lag: record both together for longer, or lower --max-lag");
  }
  r.confidence = TcConfidence(fixed, first, last, moving, r.tracker_lag_s, r.coarse_step_s, o);
  r.correlation = r.confidence.peak_r;
  const LagConfidence& c = r.confidence;
  const auto lag_r = [](double lag, double rr) {
    return TcNum(lag, 4) + " s (r " + TcNum(rr, 4) + ")";
  };
  const double misfit_limit = o.similar_misfit_ratio * (1.0 - c.peak_r) + 1e-3;
  if (c.peak_r < o.min_peak_r) {
    throw std::invalid_argument(both + ": at the best lag " + TcNum(r.tracker_lag_s, 4) +
                                " s the reflector depth and the probe position agree poorly (r " +
                                TcNum(c.peak_r, 3) + " < " + TcNum(o.min_peak_r, 2) +
                                "): the data cannot support a lag");
  }
  if (!std::isnan(c.second_r) && 1.0 - c.second_r <= misfit_limit) {
    throw std::invalid_argument(both + ": the correlation has two peaks of similar height, at " +
                                lag_r(c.peak_lag_s, c.peak_r) + " and " +
                                lag_r(c.second_lag_s, c.second_r) +
                                "; the data cannot tell which is the lag (a motion too regular "
                                "for the search window: vary it, or lower --max-lag)");
  }
  if (1.0 - c.other_polarity_r <= misfit_limit) {
    throw std::invalid_argument(
        both + ": both polarities fit: the tracker as is at " +
        lag_r(r.inverted ? c.other_polarity_lag_s : c.peak_lag_s,
              r.inverted ? c.other_polarity_r : c.peak_r) +
        " and negated at " +
        lag_r(r.inverted ? c.peak_lag_s : c.other_polarity_lag_s,
              r.inverted ? c.peak_r : c.other_polarity_r) +
        "; PLUS would keep the smaller |lag|, but the data cannot tell them apart (a "
        "symmetric motion: move the probe less regularly)");
  }
  if (!(c.lag_sd_s <= o.max_lag_sd_s)) {
    throw std::invalid_argument(both + ": the correlation peak at " +
                                lag_r(c.peak_lag_s, c.peak_r) + " is too flat: the lag's SD is " +
                                TcMs(c.lag_sd_s) + " (limit " + TcMs(o.max_lag_sd_s) +
                                "); record faster or longer motion");
  }
  return r;
}

}  // namespace echoservo::tracking

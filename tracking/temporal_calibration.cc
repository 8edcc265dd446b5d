#include "tracking/temporal_calibration.h"

#include <Eigen/Eigenvalues>
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

std::string TcNum(double v, int precision = 3) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(precision);
  s << v;
  return s.str();
}

std::string TcFrameName(std::size_t i) { return "frame " + std::to_string(i); }

double TcPeakToPeak(const std::vector<double>& v) {
  if (v.empty()) return 0.0;
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return *hi - *lo;
}

double TcMedian(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Linear interpolation of a signal with increasing times; `hint` walks forward with
// increasing query times. Only called inside [t.front(), t.back()].
double TcInterpolate(const TimedSignal& s, double t, std::size_t* hint) {
  std::size_t i = *hint;
  while (i + 2 < s.t_s.size() && s.t_s[i + 1] < t) ++i;
  while (i > 0 && s.t_s[i] > t) --i;
  *hint = i;
  const double t0 = s.t_s[i], t1 = s.t_s[i + 1];
  const double w = t1 > t0 ? std::clamp((t - t0) / (t1 - t0), 0.0, 1.0) : 0.0;
  return (1.0 - w) * s.value[i] + w * s.value[i + 1];
}

// Pearson correlation of video[i] (i in [first, last]) and tracker(t_i + lag).
double TcCorrelationAt(const TimedSignal& video, std::size_t first, std::size_t last,
                       const TimedSignal& tracker, double lag) {
  double sv = 0, st = 0, svv = 0, stt = 0, svt = 0;
  std::size_t hint = 0;
  const double n = static_cast<double>(last - first + 1);
  for (std::size_t i = first; i <= last; ++i) {
    const double v = video.value[i];
    const double x = TcInterpolate(tracker, video.t_s[i] + lag, &hint);
    sv += v;
    st += x;
    svv += v * v;
    stt += x * x;
    svt += v * x;
  }
  const double cov = svt - sv * st / n;
  const double vv = svv - sv * sv / n, tt = stt - st * st / n;
  if (!(vv > 0.0) || !(tt > 0.0)) return 0.0;
  return cov / std::sqrt(vv * tt);
}

struct TcBest {
  double lag_s = 0.0;
  double r = -2.0;
};

// The maximum of sign·r over a scan from `from` to `to` in steps of `step`.
TcBest TcScan(const TimedSignal& video, std::size_t first, std::size_t last,
              const TimedSignal& tracker, double from, double to, double step, double sign,
              std::vector<double>* lags = nullptr, std::vector<double>* rs = nullptr) {
  TcBest best;
  const auto n = static_cast<long>(std::floor((to - from) / step + 1e-9));
  for (long k = 0; k <= n; ++k) {
    const double lag = from + static_cast<double>(k) * step;
    const double r = TcCorrelationAt(video, first, last, tracker, lag);
    if (lags != nullptr) {
      lags->push_back(lag);
      rs->push_back(r);
    }
    if (sign * r > best.r) best = {lag, sign * r};
  }
  return best;
}

// Coarse then fine scan and a parabola through the best fine value and its neighbours.
TcBest TcFindLag(const TimedSignal& video, std::size_t first, std::size_t last,
                 const TimedSignal& tracker, const LagOptions& o, double coarse_step, double sign) {
  const TcBest coarse =
      TcScan(video, first, last, tracker, -o.max_lag_s, o.max_lag_s, coarse_step, sign);
  const double from = std::max(-o.max_lag_s, coarse.lag_s - 3.0 * coarse_step);
  const double to = std::min(o.max_lag_s, coarse.lag_s + 3.0 * coarse_step);
  TcBest fine = TcScan(video, first, last, tracker, from, to, o.resolution_s, sign);
  const double h = o.resolution_s;
  if (fine.lag_s - h >= -o.max_lag_s && fine.lag_s + h <= o.max_lag_s) {
    const double rm = sign * TcCorrelationAt(video, first, last, tracker, fine.lag_s - h);
    const double rp = sign * TcCorrelationAt(video, first, last, tracker, fine.lag_s + h);
    const double denom = rm - 2.0 * fine.r + rp;
    if (denom < 0.0) {
      const double delta = std::clamp(0.5 * (rm - rp) / denom, -0.5, 0.5);
      fine.lag_s += delta * h;
      fine.r = sign * TcCorrelationAt(video, first, last, tracker, fine.lag_s);
    }
  }
  return fine;
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
    if (s.width < 3 || s.height < 3 ||
        f.pixels.size() != static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height))
      throw std::invalid_argument(source + ": " + TcFrameName(i) + " has " +
                                  std::to_string(f.pixels.size()) + " pixels, not " +
                                  std::to_string(s.width) + " x " + std::to_string(s.height) +
                                  " (at least 3 x 3)");
  }
  // The static background: the per-pixel median of up to 31 frames spread over the sweep.
  // The moving reflector lights a pixel in few of them, so the median is what does not move
  // (the transducer's ring-down, reverberations of the housing, a fixed overlay), removed
  // from every frame before the line is searched.
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
    if (f.t_s <= previous) {
      if (f.t_s == previous) {
        ++s.duplicates;
        continue;
      }
      throw std::invalid_argument(source + ": " + TcFrameName(i) + " timestamp " + TcNum(f.t_s, 6) +
                                  " s is before the previous frame's " + TcNum(previous, 6) + " s");
    }
    previous = f.t_s;
    for (std::size_t p = 0; p < n_px; ++p)
      moving[p] = f.pixels[p] > background[p]
                      ? static_cast<std::uint8_t>(f.pixels[p] - background[p])
                      : std::uint8_t{0};
    const std::optional<ReflectorLine> found = FindReflectorLine(moving, f.width, f.height, line);
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
  if (nx < 3 || (thin_volume ? nz : ny) < 3)
    throw std::invalid_argument(source + ": frames of " + std::to_string(nx) + " x " +
                                std::to_string(thin_volume ? nz : ny) +
                                " pixels (lateral x depth); a reflector line needs at least 3 x 3");
  const int width = nx;
  const int height = thin_volume ? nz : ny;
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
  s.spacing_mm = thin_volume ? video.spacing_mm[2] : video.spacing_mm[1];
  return s;
}

TrackerSignal ProbeMotionSignal(const imaging::PlusSequence& tracker, const std::string& tool,
                                const std::string& source) {
  const std::vector<std::string> tools = imaging::PlusTrackerTools(tracker);
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
  if (name.empty()) {
    if (std::find(tools.begin(), tools.end(), "ProbeToTracker") != tools.end())
      name = "ProbeToTracker";
    else if (tools.size() == 1)
      name = tools.front();
    else
      throw std::invalid_argument(source +
                                  ": no ProbeToTracker transform; name the probe's tool "
                                  "with --tool (tools in the file: " +
                                  list() + ")");
  } else if (std::find(tools.begin(), tools.end(), name) == tools.end()) {
    throw std::invalid_argument(source + ": no tool " + name +
                                " in the file (tools in the file: " + list() + ")");
  }
  TrackerSignal s;
  s.tool = name;
  s.frames = tracker.frames.size();
  std::vector<double> t;
  std::vector<Eigen::Vector3d> p;
  for (std::size_t i = 0; i < tracker.frames.size(); ++i) {
    const imaging::SequenceFrame& f = tracker.frames[i];
    if (!f.TransformValid(name)) {
      ++s.not_ok[f.TransformStatus(name).value_or("absent")];
      continue;
    }
    const auto time = f.Timestamp();
    if (!time) throw std::invalid_argument(source + ": " + TcFrameName(i) + " has no Timestamp");
    const Eigen::Matrix4d m = *f.Transform(name);
    if (!t.empty() && *time <= t.back()) {
      if (*time == t.back()) {
        ++s.duplicates;
        continue;
      }
      throw std::invalid_argument(source + ": " + TcFrameName(i) + " timestamp " + TcNum(*time, 6) +
                                  " s is before the previous frame's " + TcNum(t.back(), 6) + " s");
    }
    t.push_back(*time);
    p.push_back(m.block<3, 1>(0, 3));
  }
  if (t.size() < 2) {
    std::string statuses;
    for (const auto& [status, n] : s.not_ok)
      statuses += (statuses.empty() ? "" : ", ") + status + " " + std::to_string(n);
    throw std::invalid_argument(source + ": tool " + name + " has " + std::to_string(t.size()) +
                                " OK transform(s) in " + std::to_string(s.frames) + " frames (" +
                                (statuses.empty() ? "none" : statuses) +
                                "): no probe motion to calibrate with");
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& q : p) mean += q;
  mean /= static_cast<double>(p.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& q : p) cov += (q - mean) * (q - mean).transpose();
  cov /= static_cast<double>(p.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  s.axis = eig.eigenvectors().col(2);  // eigenvalues ascending
  // A fixed sign (largest component positive) so that the signal does not flip between runs.
  Eigen::Index largest = 0;
  s.axis.cwiseAbs().maxCoeff(&largest);
  if (s.axis[largest] < 0.0) s.axis = -s.axis;
  s.spread_mm = eig.eigenvalues().reverse().cwiseMax(0.0).cwiseSqrt();
  s.position_mm.t_s = std::move(t);
  for (const Eigen::Vector3d& q : p) s.position_mm.value.push_back((q - mean).dot(s.axis));
  return s;
}

LagResult EstimateTrackerLag(const TimedSignal& video, const TimedSignal& tracker,
                             const LagOptions& o, const std::string& video_source,
                             const std::string& tracker_source) {
  if (!(o.max_lag_s > 0.0) || !(o.resolution_s >= 1e-5) || o.resolution_s > o.max_lag_s ||
      !(o.min_tracker_p2p_mm >= 0.0) || !(o.min_video_p2p_px >= 0.0) || o.min_samples < 3 ||
      !(o.polarity_tolerance >= 0.0)) {
    throw std::invalid_argument(
        "temporal calibration: options out of range (max_lag_s > 0, resolution_s in "
        "[1e-5, max_lag_s], peak-to-peak limits ≥ 0, min_samples ≥ 3)");
  }
  if (tracker.size() < 2)
    throw std::invalid_argument(tracker_source + ": fewer than 2 tracker samples");
  if (video.size() < 2)
    throw std::invalid_argument(video_source + ": " + std::to_string(video.size()) +
                                " frame(s) with a reflector line (a bright straight line across "
                                "at least 30 % of the columns); a water-tank bottom sweep is "
                                "needed");
  // The video samples compared: those whose t ± max_lag lies in the tracker's span, so that
  // every trial lag compares the same samples.
  const double from = tracker.t_s.front() + o.max_lag_s;
  const double to = tracker.t_s.back() - o.max_lag_s;
  const auto first_it = std::lower_bound(video.t_s.begin(), video.t_s.end(), from);
  const auto last_it = std::upper_bound(video.t_s.begin(), video.t_s.end(), to);
  const auto count = static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, last_it - first_it));
  if (count < o.min_samples) {
    throw std::invalid_argument(
        video_source + " and " + tracker_source + ": " + std::to_string(count) +
        " video frames lie at least max lag " + TcNum(o.max_lag_s, 3) +
        " s inside the tracker's time span " + TcNum(tracker.t_s.front(), 3) + " … " +
        TcNum(tracker.t_s.back(), 3) + " s (video " + TcNum(video.t_s.front(), 3) + " … " +
        TcNum(video.t_s.back(), 3) + " s); " + std::to_string(o.min_samples) +
        " are needed: record both together for longer, or lower --max-lag");
  }
  LagResult r;
  const auto first = static_cast<std::size_t>(first_it - video.t_s.begin());
  const std::size_t last = first + count - 1;
  r.video_samples_used = count;
  r.window_from_s = video.t_s[first];
  r.window_to_s = video.t_s[last];
  std::vector<double> vv(video.value.begin() + static_cast<std::ptrdiff_t>(first),
                         video.value.begin() + static_cast<std::ptrdiff_t>(last) + 1);
  std::vector<double> tv;
  for (std::size_t i = 0; i < tracker.size(); ++i) {
    if (tracker.t_s[i] >= r.window_from_s - o.max_lag_s &&
        tracker.t_s[i] <= r.window_to_s + o.max_lag_s)
      tv.push_back(tracker.value[i]);
  }
  r.tracker_samples_used = tv.size();
  r.video_p2p_px = TcPeakToPeak(vv);
  r.tracker_p2p_mm = TcPeakToPeak(tv);
  if (r.tracker_p2p_mm < o.min_tracker_p2p_mm) {
    throw std::invalid_argument(
        tracker_source + ": the probe moves " + TcNum(r.tracker_p2p_mm, 2) +
        " mm peak-to-peak along its principal direction over the frames used; temporal "
        "calibration needs at least " +
        TcNum(o.min_tracker_p2p_mm, 1) + " mm (not enough motion to correlate)");
  }
  if (r.video_p2p_px < o.min_video_p2p_px) {
    throw std::invalid_argument(video_source + ": the reflector moves " + TcNum(r.video_p2p_px, 1) +
                                " pixels peak-to-peak in the frames used; temporal calibration "
                                "needs at least " +
                                TcNum(o.min_video_p2p_px, 1) + " (not enough motion to correlate)");
  }
  std::vector<double> periods;
  for (std::size_t i = first + 1; i <= last; ++i)
    periods.push_back(video.t_s[i] - video.t_s[i - 1]);
  r.coarse_step_s = std::clamp(TcMedian(periods), o.resolution_s, o.max_lag_s);

  // The coarse scan for the record (unflipped r), then each polarity's best lag.
  TcScan(video, first, last, tracker, -o.max_lag_s, o.max_lag_s, r.coarse_step_s, 1.0,
         &r.scan_lag_s, &r.scan_r);
  const TcBest direct = TcFindLag(video, first, last, tracker, o, r.coarse_step_s, 1.0);
  const TcBest inverted = TcFindLag(video, first, last, tracker, o, r.coarse_step_s, -1.0);
  const double best_r = std::max(direct.r, inverted.r);
  const bool direct_ok = direct.r >= best_r - o.polarity_tolerance;
  const bool inverted_ok = inverted.r >= best_r - o.polarity_tolerance;
  bool use_inverted = !direct_ok;
  if (direct_ok && inverted_ok) use_inverted = std::abs(inverted.lag_s) < std::abs(direct.lag_s);
  const TcBest& chosen = use_inverted ? inverted : direct;
  const TcBest& other = use_inverted ? direct : inverted;
  r.inverted = use_inverted;
  r.tracker_lag_s = chosen.lag_s;
  r.correlation = chosen.r;
  r.other_lag_s = other.lag_s;
  r.other_correlation = other.r;
  if (std::abs(r.tracker_lag_s) > o.max_lag_s - r.coarse_step_s) {
    throw std::invalid_argument(video_source + " and " + tracker_source + ": the best lag " +
                                TcNum(r.tracker_lag_s, 4) + " s lies at the edge of the search " +
                                "window ±" + TcNum(o.max_lag_s, 3) +
                                " s; the true lag may lie beyond it (raise --max-lag)");
  }
  return r;
}

}  // namespace echoservo::tracking

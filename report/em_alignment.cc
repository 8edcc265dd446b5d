#include "report/em_alignment.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <string>

namespace echoservo::report {
namespace {

constexpr double kNoValue = std::numeric_limits<double>::quiet_NaN();
constexpr double kMaxGapPeriods = 2.5;  // default max_gap_s in EM periods
constexpr double kMinPairShare = 0.8;   // of the most pairs any offset gives
constexpr std::size_t kMaxGridPoints = 4000;
constexpr double kInch = 25.4;
constexpr double kUnitTolerance = 0.1;        // relative, for naming a units mix-up
constexpr double kStaticScale = 2.0 * kInch;  // beyond: the EM sensor did not follow the tip

std::string Num(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

double MedianOf(std::vector<double> v) {
  if (v.empty()) return kNoValue;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

struct Pairs {
  Eigen::Matrix3Xd em;   // EM positions interpolated at the image times
  Eigen::Matrix3Xd img;  // image tip positions
};

Pairs Collect(const PointSeries& em, const PointSeries& img, double offset_s, double max_gap_s) {
  std::vector<Eigen::Vector3d> a, b;
  for (std::size_t i = 0; i < img.size(); ++i) {
    if (const auto p = em.At(img.t_s[i] - offset_s, max_gap_s)) {
      a.push_back(*p);
      b.push_back(img.p_mm[i]);
    }
  }
  Pairs pairs{Eigen::Matrix3Xd(3, a.size()), Eigen::Matrix3Xd(3, b.size())};
  for (std::size_t i = 0; i < a.size(); ++i) {
    pairs.em.col(static_cast<Eigen::Index>(i)) = a[i];
    pairs.img.col(static_cast<Eigen::Index>(i)) = b[i];
  }
  return pairs;
}

Eigen::Isometry3d RigidFit(const Pairs& p) {
  Eigen::Isometry3d t;
  t.matrix() = Eigen::umeyama(p.em, p.img, false);
  return t;
}

double ResidualRms(const Pairs& p, const Eigen::Isometry3d& em_to_image) {
  const Eigen::Matrix3Xd r =
      (em_to_image.linear() * p.em).colwise() + em_to_image.translation() - p.img;
  return std::sqrt(r.colwise().squaredNorm().mean());
}

// Principal standard deviations of the points, largest first.
Eigen::Vector3d Spread(const Eigen::Matrix3Xd& points) {
  const Eigen::Matrix3Xd centred = points.colwise() - points.rowwise().mean();
  const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3Xd>(centred).singularValues();
  return sv / std::sqrt(static_cast<double>(points.cols()));
}

Eigen::Matrix3Xd Points(const PointSeries& s) {
  Eigen::Matrix3Xd m(3, s.size());
  for (std::size_t i = 0; i < s.size(); ++i) m.col(static_cast<Eigen::Index>(i)) = s.p_mm[i];
  return m;
}

[[noreturn]] void Refuse(const std::string& why) {
  throw std::invalid_argument("EM-to-image alignment: " + why);
}

void CheckScale(const Pairs& p, double max_error, double* scale) {
  const double em_spread = Spread(p.em)[0], image_spread = Spread(p.img)[0];
  if (!(em_spread * kStaticScale > image_spread)) {
    Refuse("the EM sensor hardly moved (principal spread " + Num(em_spread, 3) +
           " mm) while the tracked tip moved " + Num(image_spread, 2) +
           " mm: the EM log does not follow this run's catheter (wrong sensor or file?)");
  }
  const Eigen::Matrix4d s = Eigen::umeyama(p.em, p.img, true);
  *scale = s.block<3, 1>(0, 0).norm();
  if (std::abs(*scale - 1.0) <= max_error) return;
  std::string hint = "check the EM log's units (--em-units) and that it belongs to this run";
  if (std::abs(*scale / kInch - 1.0) < kUnitTolerance) {
    hint = "the EM log looks like inches read as mm: declare --em-units in";
  } else if (std::abs(*scale * kInch - 1.0) < kUnitTolerance) {
    hint = "the EM log looks like mm declared as inches: declare --em-units mm";
  }
  Refuse("the tracked tip moves " + Num(*scale, 3) +
         " times as far as the EM sensor (a rigid transform needs 1); " + hint);
}

template <typename T>
double ValueOf(const T& jet) {
  return jet.a;
}
inline double ValueOf(double v) { return v; }

// One image tip against the EM track interpolated at t_image − offset and mapped by
// rotation (angle-axis, about the EM centroid) and translation.
struct PairCost {
  const PointSeries* em;
  Eigen::Vector3d em_centroid;
  double t_image_s;
  Eigen::Vector3d image_mm;

  template <typename T>
  bool operator()(const T* rotation, const T* translation, const T* offset, T* residual) const {
    const T t = T(t_image_s) - offset[0];
    const auto& times = em->t_s;
    const auto upper = std::upper_bound(times.begin(), times.end(), ValueOf(t));
    const std::size_t k = static_cast<std::size_t>(std::clamp<std::ptrdiff_t>(
        upper - times.begin() - 1, 0, static_cast<std::ptrdiff_t>(times.size()) - 2));
    const T f = (t - T(times[k])) / T(times[k + 1] - times[k]);
    T p[3];
    for (int j = 0; j < 3; ++j) {
      p[j] = T(em->p_mm[k][j] - em_centroid[j]) + f * T(em->p_mm[k + 1][j] - em->p_mm[k][j]);
    }
    T q[3];
    ceres::AngleAxisRotatePoint(rotation, p, q);
    for (int j = 0; j < 3; ++j) residual[j] = q[j] + translation[j] - T(image_mm[j]);
    return true;
  }
};

}  // namespace

void PointSeries::Add(double t, const Eigen::Vector3d& p) {
  assert(t_s.empty() || t > t_s.back());
  t_s.push_back(t);
  p_mm.push_back(p);
}

std::optional<Eigen::Vector3d> PointSeries::At(double t, double max_gap_s) const {
  if (t_s.empty() || t < t_s.front() || t > t_s.back()) return std::nullopt;
  const auto upper = std::upper_bound(t_s.begin(), t_s.end(), t);
  if (upper == t_s.end()) return p_mm.back();  // t is the last time
  const auto k = static_cast<std::size_t>(upper - t_s.begin());
  const double dt = t_s[k] - t_s[k - 1];
  if (dt > max_gap_s) return std::nullopt;
  const double f = (t - t_s[k - 1]) / dt;
  return p_mm[k - 1] + f * (p_mm[k] - p_mm[k - 1]);
}

double PointSeries::MedianPeriodS() const {
  std::vector<double> dt;
  for (std::size_t i = 1; i < t_s.size(); ++i) dt.push_back(t_s[i] - t_s[i - 1]);
  return MedianOf(std::move(dt));
}

PointSeries ValidEmPoints(const formats::EmLog& log) {
  PointSeries s;
  for (const formats::EmSample& e : log.samples) {
    if (e.valid) s.Add(e.t_s, e.position_mm);
  }
  return s;
}

std::vector<AlignmentCheck> CheckAlignment(const PointSeries& em, const PointSeries& image,
                                           const EmAlignment& a, const AlignmentCheckLimits& l) {
  std::vector<AlignmentCheck> checks;
  const Pairs p = Collect(em, image, a.em_time_offset_s, a.max_gap_s);
  const auto n = p.em.cols();

  AlignmentCheck reg{"registration", a.residual_rms_mm, l.max_registration_rms_mm, true, ""};
  reg.passed = a.residual_rms_mm <= l.max_registration_rms_mm;
  if (!reg.passed) {
    reg.message = "registration RMS " + Num(a.residual_rms_mm, 3) + " mm exceeds the " +
                  Num(l.max_registration_rms_mm, 2) + " mm bound (EM tracker " +
                  Num(AlignmentCheckLimits::kEmTrackerAccuracyMm, 2) + " mm + detector " +
                  Num(AlignmentCheckLimits::kDetectorTipAccuracyMm, 2) +
                  " mm): the EM log does not follow this run's tip (wrong log, sensor or "
                  "transform?)";
  }
  checks.push_back(reg);

  // The search window is centre ± max_offset; an offset on its edge means the true one may
  // lie beyond it. A window narrower than two grid steps pins the offset: nothing to check.
  const double from_centre = std::abs(a.em_time_offset_s - a.offset_center_s);
  AlignmentCheck off{"clock offset", from_centre, a.max_offset_s - a.grid_step_s, true, ""};
  if (a.max_offset_s >= 2.0 * a.grid_step_s) {
    off.passed = from_centre <= off.bound;
    if (!off.passed) {
      off.message = "the clock offset " + Num(a.em_time_offset_s, 4) +
                    " s lies at the edge of the search window " + Num(a.offset_center_s, 3) +
                    " ± " + Num(a.max_offset_s, 3) + " s (" + Num(from_centre, 3) +
                    " s from its centre, more than " + Num(off.bound, 3) +
                    " s): the true offset is likely beyond it (a log of another time?); widen "
                    "--max-offset or set --offset-center";
    }
  }
  checks.push_back(off);

  AlignmentCheck cor{"motion correlation", 0.0, l.min_motion_correlation, true, ""};
  double em_spread = 0.0, tip_spread = 0.0;
  if (n >= 2) {
    const Eigen::Matrix3Xd mapped =
        (a.em_to_image.linear() * p.em).colwise() + a.em_to_image.translation();
    const Eigen::Matrix3Xd centred = p.img.colwise() - p.img.rowwise().mean();
    const Eigen::Vector3d axis =
        Eigen::JacobiSVD<Eigen::Matrix3Xd>(centred, Eigen::ComputeThinU).matrixU().col(0);
    const Eigen::RowVectorXd x = axis.transpose() * mapped, y = axis.transpose() * p.img;
    const Eigen::RowVectorXd xc = x.array() - x.mean(), yc = y.array() - y.mean();
    const double sxx = xc.squaredNorm(), syy = yc.squaredNorm();
    cor.value = sxx > 0.0 && syy > 0.0 ? xc.dot(yc) / std::sqrt(sxx * syy) : 0.0;
    em_spread = Spread(p.em)[0];
    tip_spread = Spread(p.img)[0];
  }
  cor.passed = cor.value >= l.min_motion_correlation;
  if (!cor.passed) {
    cor.message = "the EM sensor's motion does not follow the tracked tip's: correlation " +
                  Num(cor.value, 3) + " along the tip's principal axis (at least " +
                  Num(l.min_motion_correlation, 2) + " needed); principal spread EM " +
                  Num(em_spread, 3) + " mm, tracked tip " + Num(tip_spread, 3) +
                  " mm (wrong sensor or file?)";
  }
  checks.push_back(cor);

  double paired_span = 0.0;
  {
    double first = kNoValue, last = kNoValue;
    for (std::size_t i = 0; i < image.size(); ++i) {
      if (!em.At(image.t_s[i] - a.em_time_offset_s, a.max_gap_s)) continue;
      if (!std::isfinite(first)) first = image.t_s[i];
      last = image.t_s[i];
    }
    if (std::isfinite(first)) paired_span = last - first;
  }
  const double span = image.size() >= 2 ? image.t_s.back() - image.t_s.front() : 0.0;
  AlignmentCheck ov{"overlap", span > 0.0 ? paired_span / span : 0.0, l.min_overlap_share, true,
                    ""};
  ov.passed = ov.value >= l.min_overlap_share;
  if (!ov.passed) {
    ov.message = "the EM log overlaps " + Num(paired_span, 2) + " s of the tracked tips' " +
                 Num(span, 2) + " s (" + Num(100.0 * ov.value, 0) + " %; at least " +
                 Num(100.0 * l.min_overlap_share, 0) + " % needed: a log of another run?)";
  }
  checks.push_back(ov);
  return checks;
}

double RotationAngleDeg(const Eigen::Isometry3d& transform) {
  return Eigen::AngleAxisd(transform.rotation()).angle() * 180.0 / std::numbers::pi;
}

EmAlignment AlignEmToImage(const PointSeries& em, const PointSeries& image,
                           const EmAlignmentOptions& o) {
  if (!(o.max_offset_s >= 0.0) || !(o.grid_step_s >= 0.0) || !(o.max_gap_s >= 0.0) ||
      !(o.min_spread_mm > 0.0) || !(o.huber_mm >= 0.0) || !(o.max_scale_error > 0.0) ||
      o.min_pairs < 3 || (o.fixed_offset_s && !std::isfinite(*o.fixed_offset_s))) {
    throw std::invalid_argument(
        "EM-to-image alignment: options out of range (max_offset_s, grid_step_s, max_gap_s, "
        "huber_mm ≥ 0; min_spread_mm, max_scale_error > 0; min_pairs ≥ 3)");
  }
  const std::size_t need = o.min_pairs;
  if (em.size() < need) {
    Refuse("the EM log has " + std::to_string(em.size()) + " valid samples; at least " +
           std::to_string(need) + " are needed");
  }
  if (image.size() < need) {
    Refuse("the run has " + std::to_string(image.size()) +
           " volumes with a tracked tip; at least " + std::to_string(need) + " are needed");
  }
  EmAlignment a;
  a.fixed_transform = o.em_to_image.has_value();
  a.spread_mm = Spread(Points(image));
  if (a.spread_mm[0] < o.min_spread_mm) {
    Refuse("the tracked tip hardly moved (principal spread " + Num(a.spread_mm[0], 3) + " mm < " +
           Num(o.min_spread_mm, 3) +
           " mm), so neither the clock offset nor the pose can be estimated: record the tip "
           "moving");
  }
  if (!a.fixed_transform && a.spread_mm[1] < o.min_spread_mm) {
    Refuse("the tracked tip moved along a line (principal spreads " + Num(a.spread_mm[0], 2) +
           ", " + Num(a.spread_mm[1], 2) + ", " + Num(a.spread_mm[2], 2) +
           " mm; the second must be at least " + Num(o.min_spread_mm, 2) +
           " mm), so the rotation about that line is unobservable: record a registration "
           "sweep that moves the tip in two directions, or give the EM-to-image transform "
           "(--em-to-image)");
  }

  const double em_period = em.MedianPeriodS();
  const double max_gap = o.max_gap_s > 0.0 ? o.max_gap_s : kMaxGapPeriods * em_period;
  a.max_gap_s = max_gap;
  a.fixed_offset = o.fixed_offset_s.has_value();
  a.offset_center_s = a.fixed_offset                     ? *o.fixed_offset_s
                      : std::isfinite(o.offset_center_s) ? o.offset_center_s
                                                         : image.t_s.front() - em.t_s.front();
  a.max_offset_s = a.fixed_offset ? 0.0 : o.max_offset_s;
  const double window = 2.0 * a.max_offset_s;
  a.grid_step_s = o.grid_step_s > 0.0 ? o.grid_step_s
                                      : std::max(0.5 * std::min(em_period, image.MedianPeriodS()),
                                                 window / static_cast<double>(kMaxGridPoints));
  const auto steps = static_cast<long>(std::floor(a.max_offset_s / a.grid_step_s));

  // Coarse grid: the closed-form pose (or the given one) at every offset.
  std::vector<std::size_t> counts;
  std::size_t most = 0;
  for (long k = -steps; k <= steps; ++k) {
    const double offset = a.offset_center_s + static_cast<double>(k) * a.grid_step_s;
    const Pairs p = Collect(em, image, offset, max_gap);
    const auto n = static_cast<std::size_t>(p.em.cols());
    a.grid_offset_s.push_back(offset);
    counts.push_back(n);
    most = std::max(most, n);
    a.grid_rms_mm.push_back(
        n < need ? kNoValue : ResidualRms(p, a.fixed_transform ? *o.em_to_image : RigidFit(p)));
  }
  if (most < need) {
    Refuse("at most " + std::to_string(most) + " image tips pair with EM samples (at least " +
           std::to_string(need) + " are needed) for clock offsets in " + Num(a.offset_center_s, 3) +
           " ± " + Num(a.max_offset_s, 3) +
           " s: check that the EM log belongs to this run and the offset window" +
           (a.fixed_offset ? " (the given tracker lag)" : ""));
  }
  std::size_t best = a.grid_rms_mm.size();
  const double floor_count =
      std::max<double>(static_cast<double>(need), kMinPairShare * static_cast<double>(most));
  for (std::size_t i = 0; i < a.grid_rms_mm.size(); ++i) {
    if (static_cast<double>(counts[i]) < floor_count || !std::isfinite(a.grid_rms_mm[i])) continue;
    if (best == a.grid_rms_mm.size() || a.grid_rms_mm[i] < a.grid_rms_mm[best]) best = i;
  }
  assert(best < a.grid_rms_mm.size());
  a.coarse_offset_s = a.grid_offset_s[best];
  const Pairs coarse = Collect(em, image, a.coarse_offset_s, max_gap);
  Eigen::Isometry3d start = a.fixed_transform ? *o.em_to_image : RigidFit(coarse);
  if (!a.fixed_transform) CheckScale(coarse, o.max_scale_error, &a.similarity_scale);

  // Ceres: offset and pose together; the pairs are those of the coarse offset.
  const Eigen::Vector3d centroid = coarse.em.rowwise().mean();
  const Eigen::Matrix3d r0 = start.linear();
  double rotation[3];
  const Eigen::AngleAxisd aa(r0);
  for (int j = 0; j < 3; ++j) rotation[j] = aa.angle() * aa.axis()[j];
  Eigen::Vector3d tr = start.translation() + r0 * centroid;
  double translation[3] = {tr[0], tr[1], tr[2]};
  double offset[1] = {a.coarse_offset_s};
  ceres::Problem problem;
  for (std::size_t i = 0; i < image.size(); ++i) {
    if (!em.At(image.t_s[i] - a.coarse_offset_s, max_gap)) continue;
    auto* cost = new ceres::AutoDiffCostFunction<PairCost, 3, 3, 3, 1>(
        new PairCost{&em, centroid, image.t_s[i], image.p_mm[i]});
    problem.AddResidualBlock(cost, o.huber_mm > 0.0 ? new ceres::HuberLoss(o.huber_mm) : nullptr,
                             rotation, translation, offset);
  }
  if (a.fixed_transform) {
    problem.SetParameterBlockConstant(rotation);
    problem.SetParameterBlockConstant(translation);
  }
  if (a.fixed_offset) {
    problem.SetParameterBlockConstant(offset);
  } else {
    problem.SetParameterLowerBound(offset, 0, a.offset_center_s - o.max_offset_s - a.grid_step_s);
    problem.SetParameterUpperBound(offset, 0, a.offset_center_s + o.max_offset_s + a.grid_step_s);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = 100;
  so.function_tolerance = 1e-12;
  so.parameter_tolerance = 1e-12;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  if (!(a.fixed_transform && a.fixed_offset)) {  // else nothing is left to estimate
    ceres::Solve(so, &problem, &summary);
    a.iterations = static_cast<int>(summary.iterations.size());
  }

  Eigen::Matrix3d r;
  ceres::AngleAxisToRotationMatrix(rotation, r.data());  // column-major, as Eigen
  a.em_to_image.linear() = r;
  a.em_to_image.translation() =
      Eigen::Vector3d(translation[0], translation[1], translation[2]) - r * centroid;
  a.em_time_offset_s = offset[0];
  const Pairs final_pairs = Collect(em, image, a.em_time_offset_s, max_gap);
  a.pairs = static_cast<std::size_t>(final_pairs.em.cols());
  const Eigen::Matrix3Xd res = (a.em_to_image.linear() * final_pairs.em).colwise() +
                               a.em_to_image.translation() - final_pairs.img;
  a.residual_rms_mm = std::sqrt(res.colwise().squaredNorm().mean());
  a.residual_max_mm = res.colwise().norm().maxCoeff();
  return a;
}

}  // namespace echoservo::report

#include "lab/motion_model.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <type_traits>

#include "estimation/harmonic_fit.h"

namespace echoservo::lab {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr int kMaxHarmonics = 12;
constexpr double kMinRespirationHz = 0.08;
constexpr double kMaxRespirationHz = 0.7;
constexpr double kMinRateHz = 0.3;
constexpr double kMaxRateHz = 4.0;

// Positions of the parameters in the vector.
struct Layout {
  int offset = 0;
  int rate = 1;
  int drift = -1;
  int resp = -1;  // cos, sin, rate
  int harm = 2;   // a1, b1, a2, b2, …
  int harmonics = 0;
  std::vector<int> term;  // first parameter of each term
  int size = 0;
  explicit Layout(const MotionModelSpec& s) : harmonics(s.harmonics) {
    int next = 2;
    if (s.rate_drift) drift = next++;
    if (s.respiration) {
      resp = next;
      next += 3;
    }
    harm = next;
    next += 2 * s.harmonics;
    for (const MotionTerm& t : s.terms) {
      term.push_back(next);
      next += static_cast<int>(t.parameters.size());
    }
    size = next;
  }
};

bool HasFileTerms(const MotionModelSpec& s) {
  return std::any_of(s.terms.begin(), s.terms.end(),
                     [](const MotionTerm& t) { return t.kind == MotionTermKind::kFile; });
}

template <typename T>
T MotionLogistic(const T& z) {
  using std::exp;
  // Saturated (within 1e-15) with exactly zero derivatives: a step's moment that no fitted
  // sample sees (a held-out block) stays where it started instead of following the
  // Jacobi-scaled crumbs of its tails.
  if (z > 35.0) return T(1.0);
  if (z < -35.0) return T(0.0);
  if (z >= 0.0) return 1.0 / (1.0 + exp(-z));
  const T e = exp(z);
  return e / (1.0 + e);
}

// The file terms of a spec, each with its own parser (one FileTerms per fit and thread).
class FileTerms {
 public:
  FileTerms(const Layout& l, const MotionModelSpec& s) : layout_(l) {
    for (std::size_t j = 0; j < s.terms.size(); ++j) {
      if (s.terms[j].kind != MotionTermKind::kFile) continue;
      index_.push_back(j);
      evaluators_.emplace_back(s.terms[j]);
    }
  }
  bool empty() const { return index_.empty(); }
  double Phase(const double* p, double time_s) const {
    double phase = 0.0;
    for (std::size_t i = 0; i < index_.size(); ++i) {
      if (evaluators_[i].has_phase())
        phase += evaluators_[i].Phase(time_s, p + layout_.term[index_[i]]);
    }
    return phase;
  }
  double Position(const double* p, double time_s, double phase, double rate,
                  double heartbeat) const {
    double x = 0.0;
    for (std::size_t i = 0; i < index_.size(); ++i) {
      if (evaluators_[i].has_position())
        x += evaluators_[i](time_s, phase, rate, heartbeat, p + layout_.term[index_[i]]);
    }
    return x;
  }

 private:
  Layout layout_;
  std::vector<std::size_t> index_;
  std::vector<MotionTermEvaluator> evaluators_;
};

double WrapMotionPhase(double phase) {
  phase = std::fmod(phase, kTwoPi);
  return phase < 0.0 ? phase + kTwoPi : phase;
}

// The heartbeat's phase: the constant rate (+ drift) and the library phase terms.
template <typename T>
T PhaseAt(const Layout& l, const std::vector<MotionTerm>& terms, const T* p, double tau,
          double time_s) {
  using std::cos;
  using std::sin;
  T phase = kTwoPi * p[l.rate] * tau;
  if (l.drift >= 0) phase += kTwoPi * 0.5 * p[l.drift] * tau * tau;
  for (std::size_t j = 0; j < terms.size(); ++j) {
    const T* q = p + l.term[j];
    if (terms[j].kind == MotionTermKind::kRateModulation) {
      const T w = kTwoPi * time_s / q[2];
      phase += q[2] * (q[0] * sin(w) - q[1] * cos(w));
    } else if (terms[j].kind == MotionTermKind::kBeatTiming) {
      const auto n = static_cast<int>(terms[j].parameters.size());
      const double u = time_s / terms[j].knot_spacing_s;
      const int k = std::clamp(static_cast<int>(std::floor(u)), 0, std::max(n - 2, 0));
      const double f = std::clamp(u - k, 0.0, 1.0);
      phase += n == 1 ? q[0] : q[k] * (1.0 - f) + q[k + 1] * f;
    }
  }
  return phase;
}

// The harmonics' sum at `phase` (without the offset).
template <typename T>
T MotionHarmonicSum(const Layout& l, const T* p, const T& phase) {
  using std::cos;
  using std::sin;
  const T c1 = cos(phase);
  const T s1 = sin(phase);
  T ck = c1;
  T sk = s1;
  T h = T(0.0);
  for (int k = 0; k < l.harmonics; ++k) {
    h += p[l.harm + 2 * k] * ck + p[l.harm + 2 * k + 1] * sk;
    const T next = ck * c1 - sk * s1;
    sk = sk * c1 + ck * s1;
    ck = next;
  }
  return h;
}

// The phase at a sample with the file terms' phase_rad (double only).
double MotionSamplePhase(const Layout& l, const std::vector<MotionTerm>& terms,
                         const FileTerms* files, const double* p, double tau, double time_s) {
  double phase = PhaseAt(l, terms, p, tau, time_s);
  if (files != nullptr) phase += files->Phase(p, time_s);
  return phase;
}

// The heartbeat model, its library terms and (double only) its file terms.
template <typename T>
T ModelAt(const Layout& l, const std::vector<MotionTerm>& terms, const T* p, double tau,
          double time_s, const FileTerms* files = nullptr) {
  using std::cos;
  using std::sin;
  (void)files;
  T phase = PhaseAt(l, terms, p, tau, time_s);
  if constexpr (std::is_same_v<T, double>) {
    if (files != nullptr) phase += files->Phase(p, time_s);
  }
  const T h = MotionHarmonicSum(l, p, phase);
  T x = p[l.offset] + h;
  if (l.resp >= 0) {
    const T r = kTwoPi * p[l.resp + 2] * tau;
    x += p[l.resp] * cos(r) + p[l.resp + 1] * sin(r);
  }
  for (std::size_t j = 0; j < terms.size(); ++j) {
    const T* q = p + l.term[j];
    switch (terms[j].kind) {
      case MotionTermKind::kFile:
      case MotionTermKind::kRateModulation:
      case MotionTermKind::kBeatTiming:
        break;
      case MotionTermKind::kBaselineLinear:
        x += q[0] * time_s;
        break;
      case MotionTermKind::kBaselineQuadratic:
        x += q[0] * (time_s * time_s);
        break;
      case MotionTermKind::kAmplitudeGrowth: {
        const T kp = static_cast<double>(terms[j].harmonic) * phase;
        x += (q[0] * cos(kp) + q[1] * sin(kp)) * time_s;
        break;
      }
      case MotionTermKind::kBaselineStep:
        x += q[0] * MotionLogistic((time_s - q[1]) / q[2]);
        break;
      case MotionTermKind::kBaselineSine: {
        const T w = kTwoPi * time_s / q[2];
        x += q[0] * cos(w) + q[1] * sin(w);
        break;
      }
      case MotionTermKind::kAmplitudeModulation: {
        const T w = kTwoPi * time_s / q[2];
        x += h * (q[0] * cos(w) + q[1] * sin(w));
        break;
      }
    }
  }
  if constexpr (std::is_same_v<T, double>) {
    if (files != nullptr && !files->empty()) {
      const double rate = p[l.rate] + (l.drift >= 0 ? p[l.drift] * tau : 0.0);
      x += files->Position(p, time_s, WrapMotionPhase(phase), rate, h);
    }
  }
  return x;
}

double MiddleTime(const estimation::MotionTrace& t) { return 0.5 * (t.t_s.front() + t.t_s.back()); }

struct Residuals {
  Layout layout;
  const std::vector<MotionTerm>* terms;
  const estimation::MotionTrace* trace;
  std::vector<std::size_t> index;
  double t_mid;
  double sigma;
  template <typename T>
  bool operator()(T const* const* p, T* r) const {
    for (std::size_t i = 0; i < index.size(); ++i) {
      const std::size_t s = index[i];
      r[i] = (ModelAt(layout, *terms, p[0], trace->t_s[s] - t_mid,
                      trace->t_s[s] - trace->t_s.front()) -
              trace->position_mm[s]) /
             sigma;
    }
    return true;
  }
};

// With file terms: evaluated in double, differentiated by central differences.
struct NumericResiduals {
  Residuals base;
  std::shared_ptr<FileTerms> files;
  bool operator()(double const* const* p, double* r) const {
    const estimation::MotionTrace& trace = *base.trace;
    for (std::size_t i = 0; i < base.index.size(); ++i) {
      const std::size_t s = base.index[i];
      const double tau = trace.t_s[s] - base.t_mid;
      const double time = trace.t_s[s] - trace.t_s.front();
      const double x = ModelAt(base.layout, *base.terms, p[0], tau, time, files.get());
      r[i] = (x - trace.position_mm[s]) / base.sigma;
      if (!std::isfinite(r[i])) return false;
    }
    return true;
  }
};

// A term's knot penalty (beat_timing): the knot values' second differences and (weakly) the values,
// in σ.
struct BeatTimingPenalty {
  int first = 0;
  int knots = 0;
  double weight = 0.0;
  int count() const { return std::max(knots - 2, 0) + knots; }
  template <typename T>
  bool operator()(T const* const* p, T* r) const {
    const T* q = p[0] + first;
    int i = 0;
    for (int k = 1; k + 1 < knots; ++k) r[i++] = weight * (q[k - 1] - 2.0 * q[k] + q[k + 1]);
    for (int k = 0; k < knots; ++k) r[i++] = 0.05 * weight * q[k];
    return true;
  }
};

// A weak pull of every bounded term parameter towards where the fit started: one σ per
// bound width, negligible wherever the samples determine the parameter (a step's moment has
// an sd of hundredths of a second against a width of the trace). It keeps put what no fitted
// sample sees (a step whose jump lies in a held-out block), as a parameter without any
// gradient stays, instead of letting it wander on the Jacobi-scaled crumbs of a tail.
struct TermAnchor {
  std::vector<int> index;
  std::vector<double> start;
  std::vector<double> scale;
  template <typename T>
  bool operator()(T const* const* p, T* r) const {
    for (std::size_t i = 0; i < index.size(); ++i) r[i] = (p[0][index[i]] - start[i]) * scale[i];
    return true;
  }
};

// The model at every sample of `index`.
std::vector<double> Predict(const MotionModelSpec& spec, const std::vector<double>& p,
                            const estimation::MotionTrace& trace,
                            const std::vector<std::size_t>& index) {
  const Layout l(spec);
  const FileTerms files(l, spec);
  const double t_mid = MiddleTime(trace);
  std::vector<double> out;
  out.reserve(index.size());
  for (std::size_t i : index) {
    const double tau = trace.t_s[i] - t_mid;
    const double time = trace.t_s[i] - trace.t_s.front();
    out.push_back(ModelAt(l, spec.terms, p.data(), tau, time, &files));
  }
  return out;
}

std::vector<std::size_t> All(const estimation::MotionTrace& t,
                             const std::vector<std::size_t>& subset) {
  if (!subset.empty()) return subset;
  std::vector<std::size_t> all(t.size());
  std::iota(all.begin(), all.end(), 0);
  return all;
}

// Initial parameters: a rate search on the samples within the middle `fraction`.
std::vector<double> InitialGuess(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                                 const std::vector<std::size_t>& index) {
  const double t_mid = MiddleTime(trace);
  const double half = std::max(trace.duration_s() / 6.0, 2.0);
  std::vector<double> t;
  std::vector<double> x;
  for (std::size_t i : index) {
    if (std::abs(trace.t_s[i] - t_mid) <= half) {
      t.push_back(trace.t_s[i]);
      x.push_back(trace.position_mm[i]);
    }
  }
  estimation::HarmonicFitOptions o;
  o.harmonics = spec.harmonics;
  o.trend_order = 0;
  o.max_rate_hz = kMaxRateHz;
  const estimation::HarmonicFit fit =
      estimation::FitHarmonics(t.data(), x.data(), t.size(), t_mid, o);
  const Layout l(spec);
  std::vector<double> p(static_cast<std::size_t>(l.size), 0.0);
  p[0] = fit.motion.offset_mm;
  p[1] = fit.motion.frequency_hz;
  for (int k = 1; k <= spec.harmonics; ++k) {
    // The fit's phase is θ = φ + p0; rotate to φ = 2πfτ.
    const double a = fit.motion.cos_mm[static_cast<std::size_t>(k - 1)];
    const double b = fit.motion.sin_mm[static_cast<std::size_t>(k - 1)];
    const double d = k * fit.motion.phase0_rad;
    p[static_cast<std::size_t>(l.harm + 2 * (k - 1))] = a * std::cos(d) + b * std::sin(d);
    p[static_cast<std::size_t>(l.harm + 2 * (k - 1) + 1)] = -a * std::sin(d) + b * std::cos(d);
  }
  if (l.resp >= 0) p[static_cast<std::size_t>(l.resp + 2)] = 0.25;
  for (std::size_t j = 0; j < spec.terms.size(); ++j) {
    const std::vector<double>& start = spec.terms[j].start;
    std::copy(start.begin(), start.end(), p.begin() + l.term[j]);
  }
  return p;
}

void Solve(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
           const std::vector<std::size_t>& index, double sigma, std::vector<double>& p,
           ceres::Problem* keep = nullptr) {
  const Layout l(spec);
  const Residuals residuals{l, &spec.terms, &trace, index, MiddleTime(trace), sigma};
  ceres::DynamicCostFunction* cost = nullptr;
  if (HasFileTerms(spec)) {
    cost = new ceres::DynamicNumericDiffCostFunction<NumericResiduals, ceres::CENTRAL>(
        new NumericResiduals{residuals, std::make_shared<FileTerms>(residuals.layout, spec)});
  } else {
    cost = new ceres::DynamicAutoDiffCostFunction<Residuals, 8>(new Residuals(residuals));
  }
  cost->AddParameterBlock(l.size);
  cost->SetNumResiduals(static_cast<int>(index.size()));
  ceres::Problem local;
  ceres::Problem& problem = keep != nullptr ? *keep : local;
  // Starting values inside the bounds (Ceres refuses infeasible ones).
  const auto bound = [&](int at, double lower, double upper) {
    auto& v = p[static_cast<std::size_t>(at)];
    if (std::isfinite(lower)) v = std::max(v, lower);
    if (std::isfinite(upper)) v = std::min(v, upper);
  };
  bound(l.rate, kMinRateHz, kMaxRateHz);
  if (l.drift >= 0) bound(l.drift, -0.1, 0.1);
  if (l.resp >= 0) bound(l.resp + 2, kMinRespirationHz, kMaxRespirationHz);
  for (std::size_t j = 0; j < spec.terms.size(); ++j) {
    const MotionTerm& t = spec.terms[j];
    for (std::size_t q = 0; q < t.parameters.size(); ++q)
      bound(l.term[j] + static_cast<int>(q), t.lower[q], t.upper[q]);
  }
  problem.AddResidualBlock(cost, nullptr, p.data());
  for (std::size_t j = 0; j < spec.terms.size(); ++j) {
    const MotionTerm& t = spec.terms[j];
    if (!(t.penalty > 0.0) || t.penalty_knots == 0 ||
        t.penalty_first + t.penalty_knots > t.parameters.size())
      continue;
    const BeatTimingPenalty penalty{l.term[j] + static_cast<int>(t.penalty_first),
                                    static_cast<int>(t.penalty_knots), t.penalty};
    auto* pc = new ceres::DynamicAutoDiffCostFunction<BeatTimingPenalty, 8>(
        new BeatTimingPenalty(penalty));
    pc->AddParameterBlock(l.size);
    pc->SetNumResiduals(penalty.count());
    problem.AddResidualBlock(pc, nullptr, p.data());
  }
  auto anchor = std::make_unique<TermAnchor>();
  for (std::size_t j = 0; j < spec.terms.size(); ++j) {
    const MotionTerm& t = spec.terms[j];
    for (std::size_t q = 0; q < t.parameters.size(); ++q) {
      const double width = t.upper[q] - t.lower[q];
      if (!std::isfinite(width) || !(width > 0.0)) continue;
      const int at = l.term[j] + static_cast<int>(q);
      anchor->index.push_back(at);
      anchor->start.push_back(p[static_cast<std::size_t>(at)]);
      anchor->scale.push_back(1.0 / width);
    }
  }
  if (!anchor->index.empty()) {
    const auto count = static_cast<int>(anchor->index.size());
    auto* ac = new ceres::DynamicAutoDiffCostFunction<TermAnchor, 8>(anchor.release());
    ac->AddParameterBlock(l.size);
    ac->SetNumResiduals(count);
    problem.AddResidualBlock(ac, nullptr, p.data());
  }
  problem.SetParameterLowerBound(p.data(), l.rate, kMinRateHz);
  problem.SetParameterUpperBound(p.data(), l.rate, kMaxRateHz);
  for (std::size_t j = 0; j < spec.terms.size(); ++j) {
    const MotionTerm& t = spec.terms[j];
    for (std::size_t q = 0; q < t.parameters.size(); ++q) {
      const int at = l.term[j] + static_cast<int>(q);
      if (std::isfinite(t.lower[q])) problem.SetParameterLowerBound(p.data(), at, t.lower[q]);
      if (std::isfinite(t.upper[q])) problem.SetParameterUpperBound(p.data(), at, t.upper[q]);
    }
  }
  if (l.drift >= 0) {
    problem.SetParameterLowerBound(p.data(), l.drift, -0.1);
    problem.SetParameterUpperBound(p.data(), l.drift, 0.1);
  }
  if (l.resp >= 0) {
    problem.SetParameterLowerBound(p.data(), l.resp + 2, kMinRespirationHz);
    problem.SetParameterUpperBound(p.data(), l.resp + 2, kMaxRespirationHz);
  }
  ceres::Solver::Options so;
  so.max_num_iterations = 60;
  so.linear_solver_type = ceres::DENSE_QR;
  so.logging_type = ceres::SILENT;
  so.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
}

std::vector<ParameterEstimate> Estimates(const MotionModelSpec& spec,
                                         const std::vector<double>& p) {
  const Layout l(spec);
  std::vector<ParameterEstimate> e;
  e.push_back({"offset", "mm", p[0], std::nan("")});
  e.push_back({"heart_rate", "Hz", p[1], std::nan("")});
  if (l.drift >= 0)
    e.push_back({"rate_drift", "Hz/s", p[static_cast<std::size_t>(l.drift)], std::nan("")});
  if (l.resp >= 0) {
    e.push_back({"respiration_cos", "mm", p[static_cast<std::size_t>(l.resp)], std::nan("")});
    e.push_back({"respiration_sin", "mm", p[static_cast<std::size_t>(l.resp + 1)], std::nan("")});
    e.push_back({"respiration_rate", "Hz", p[static_cast<std::size_t>(l.resp + 2)], std::nan("")});
  }
  for (int k = 1; k <= l.harmonics; ++k) {
    e.push_back({"cos" + std::to_string(k), "mm", p[static_cast<std::size_t>(l.harm + 2 * (k - 1))],
                 std::nan("")});
    e.push_back({"sin" + std::to_string(k), "mm",
                 p[static_cast<std::size_t>(l.harm + 2 * (k - 1) + 1)], std::nan("")});
  }
  for (std::size_t j = 0; j < spec.terms.size(); ++j) {
    const MotionTerm& t = spec.terms[j];
    for (std::size_t q = 0; q < t.parameters.size(); ++q) {
      e.push_back({t.name + "." + t.parameters[q], t.units[q],
                   p[static_cast<std::size_t>(l.term[j]) + q], std::nan("")});
    }
  }
  return e;
}

}  // namespace

MotionModelSpec ParseMotionModel(const std::string& text) {
  const std::string catalog = " (a motion model is heartbeat:N, N in 1-12, plus any of +" +
                              std::string("respiration, +rate_drift, +harmonic, +@term.json)");
  MotionModelSpec spec;
  std::size_t start = 0;
  bool first = true;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find('+', start), text.size());
    const std::string term = text.substr(start, end - start);
    if (first) {
      if (term.rfind("heartbeat:", 0) != 0) {
        throw std::invalid_argument("--model '" + text + "': must start with heartbeat:N" +
                                    catalog);
      }
      const std::string n = term.substr(10);
      if (n.empty() || n.size() > 2 ||
          !std::all_of(n.begin(), n.end(), [](char c) { return c >= '0' && c <= '9'; }) ||
          std::stoi(n) < 1 || std::stoi(n) > kMaxHarmonics) {
        throw std::invalid_argument("--model '" + text + "': bad harmonic count '" + n + "'" +
                                    catalog);
      }
      spec.harmonics = std::stoi(n);
      first = false;
    } else if (term == "respiration") {
      spec.respiration = true;
    } else if (term == "rate_drift") {
      spec.rate_drift = true;
    } else if (term == "harmonic") {
      spec = WithMotionEffect(spec, "harmonic");
    } else if (term.size() > 1 && term[0] == '@') {
      spec.terms.push_back(ReadMotionTerm(term.substr(1)));
    } else {
      throw std::invalid_argument("--model '" + text + "': unknown term '" + term + "'" + catalog);
    }
    start = end + 1;
  }
  return spec;
}

std::string FormatMotionModel(const MotionModelSpec& s) {
  std::string out = "heartbeat:" + std::to_string(s.harmonics) +
                    (s.respiration ? "+respiration" : "") + (s.rate_drift ? "+rate_drift" : "");
  for (const MotionTerm& t : s.terms)
    out += t.kind == MotionTermKind::kFile ? "+@" + t.path : "+" + t.name;
  return out;
}

std::vector<std::string> MotionEffectNames() { return {"harmonic", "respiration", "rate_drift"}; }

std::string MotionEffectSignature(const std::string& effect) {
  if (effect == "harmonic")
    return "the residual repeats every beat: shape detail within the cardiac cycle";
  if (effect == "respiration")
    return "a slow oscillation (0.08-0.7 Hz) under the beats: the residual follows breathing";
  if (effect == "rate_drift")
    return "beats drift out of phase with a constant rate: the residual grows towards both ends";
  throw std::invalid_argument("unknown motion effect '" + effect + "'");
}

std::vector<std::string> MissingMotionEffects(const MotionModelSpec& s) {
  std::vector<std::string> out;
  if (s.harmonics < kMaxHarmonics) out.push_back("harmonic");
  if (!s.respiration) out.push_back("respiration");
  if (!s.rate_drift) out.push_back("rate_drift");
  return out;
}

MotionModelSpec WithMotionEffect(MotionModelSpec s, const std::string& effect) {
  if (effect == "harmonic") {
    if (s.harmonics >= kMaxHarmonics)
      throw std::invalid_argument("motion model: at most 12 harmonics");
    ++s.harmonics;
  } else if (effect == "respiration") {
    s.respiration = true;
  } else if (effect == "rate_drift") {
    s.rate_drift = true;
  } else {
    MotionEffectSignature(effect);  // throws for an unknown name
  }
  return s;
}

double EvaluateMotionModel(const MotionModelSpec& spec, const std::vector<double>& p,
                           const estimation::MotionTrace& trace, double noise_mm,
                           const std::vector<std::size_t>& subset) {
  const std::vector<std::size_t> index = All(trace, subset);
  const std::vector<double> x = Predict(spec, p, trace, index);
  double ss = 0.0;
  for (std::size_t i = 0; i < index.size(); ++i)
    ss += std::pow((x[i] - trace.position_mm[index[i]]) / noise_mm, 2);
  return ss / static_cast<double>(index.size());
}

MotionFit FitMotionModel(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                         double noise_mm, const std::vector<std::size_t>& subset,
                         const std::vector<double>* initial) {
  const auto t0 = std::chrono::steady_clock::now();
  ValidateMotionTrace(trace);
  if (trace.duration_s() < 2.0 / 0.6) {
    throw std::invalid_argument(trace.source + ": " + std::to_string(trace.duration_s()) +
                                " s is too short for the motion lab (two beats at 36 bpm: 3.3 s)");
  }
  if (!(noise_mm > 0.0)) throw std::invalid_argument("motion fit: the noise must be > 0");
  const Layout l(spec);
  const std::vector<std::size_t> index = All(trace, subset);
  std::vector<double> p;
  if (initial != nullptr) {
    if (initial->size() != static_cast<std::size_t>(l.size)) {
      throw std::invalid_argument("motion fit: wrong number of initial values");
    }
    p = *initial;
  } else {
    p = InitialGuess(spec, trace, index);
    // Widen from the middle third so that a drifting rate is followed.
    const double t_mid = MiddleTime(trace);
    for (double fraction : {1.0 / 3.0, 2.0 / 3.0}) {
      std::vector<std::size_t> part;
      for (std::size_t i : index) {
        if (std::abs(trace.t_s[i] - t_mid) <= 0.5 * fraction * trace.duration_s())
          part.push_back(i);
      }
      if (part.size() > static_cast<std::size_t>(2 * l.size)) Solve(spec, trace, part, noise_mm, p);
    }
  }
  ceres::Problem problem;
  Solve(spec, trace, index, noise_mm, p, &problem);

  MotionFit fit;
  fit.spec = spec;
  fit.parameters = p;
  fit.estimates = Estimates(spec, p);
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;
  ceres::Covariance covariance(co);
  const std::vector<std::pair<const double*, const double*>> block = {{p.data(), p.data()}};
  const double mse = EvaluateMotionModel(spec, p, trace, noise_mm, index);
  if (covariance.Compute(block, &problem)) {
    std::vector<double> c(static_cast<std::size_t>(l.size * l.size));
    covariance.GetCovarianceBlock(p.data(), p.data(), c.data());
    const double dof = std::max(1.0, static_cast<double>(index.size()) - l.size);
    const double chi2 = mse * static_cast<double>(index.size()) / dof;
    // Estimates are in layout order: offset, rate, [drift], [resp ×3], harmonics, terms.
    for (std::size_t i = 0; i < fit.estimates.size(); ++i) {
      fit.estimates[i].sd =
          std::sqrt(std::max(c[i * static_cast<std::size_t>(l.size) + i] * chi2, 0.0));
    }
  }
  const double t_mid = MiddleTime(trace);
  fit.prediction_mm = Predict(spec, p, trace, All(trace, {}));
  const FileTerms files(l, spec);
  double ss = 0.0;
  for (std::size_t i = 0; i < trace.size(); ++i) {
    const double phase = MotionSamplePhase(l, spec.terms, &files, p.data(), trace.t_s[i] - t_mid,
                                           trace.t_s[i] - trace.t_s.front());
    fit.phase_rad.push_back(WrapMotionPhase(phase));
    fit.heartbeat_mm.push_back(MotionHarmonicSum(l, p.data(), phase));
    ss += std::pow(fit.prediction_mm[i] - trace.position_mm[i], 2);
  }
  fit.rms_mm = std::sqrt(ss / static_cast<double>(trace.size()));
  fit.mse_norm = mse;
  fit.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return fit;
}

std::vector<double> StartMotionParameters(const MotionModelSpec& to, const MotionFit& from,
                                          const estimation::MotionTrace& trace) {
  const Layout a(from.spec);
  const Layout b(to);
  std::vector<double> p(static_cast<std::size_t>(b.size), 0.0);
  const auto& q = from.parameters;
  p[0] = q[0];
  p[1] = q[1];
  if (a.drift >= 0 && b.drift >= 0)
    p[static_cast<std::size_t>(b.drift)] = q[static_cast<std::size_t>(a.drift)];
  for (int k = 0; k < std::min(a.harmonics, b.harmonics); ++k) {
    p[static_cast<std::size_t>(b.harm + 2 * k)] = q[static_cast<std::size_t>(a.harm + 2 * k)];
    p[static_cast<std::size_t>(b.harm + 2 * k + 1)] =
        q[static_cast<std::size_t>(a.harm + 2 * k + 1)];
  }
  // Terms: the same term's fitted values, else its start values.
  for (std::size_t j = 0; j < to.terms.size(); ++j) {
    const MotionTerm& t = to.terms[j];
    std::copy(t.start.begin(), t.start.end(), p.begin() + b.term[j]);
    for (std::size_t i = 0; i < from.spec.terms.size(); ++i) {
      const MotionTerm& u = from.spec.terms[i];
      if (u.kind == t.kind && u.harmonic == t.harmonic && u.name == t.name && u.path == t.path &&
          u.parameters.size() == t.parameters.size()) {
        std::copy(q.begin() + a.term[i],
                  q.begin() + a.term[i] + static_cast<std::ptrdiff_t>(u.parameters.size()),
                  p.begin() + b.term[j]);
        break;
      }
    }
  }
  if (b.resp >= 0) {
    if (a.resp >= 0) {
      for (int j = 0; j < 3; ++j)
        p[static_cast<std::size_t>(b.resp + j)] = q[static_cast<std::size_t>(a.resp + j)];
    } else {
      // The strongest slow sinusoid in the residual.
      const double t_mid = MiddleTime(trace);
      double best = -1.0;
      for (double f = kMinRespirationHz; f <= kMaxRespirationHz; f += 0.002) {
        double cc = 0, ss = 0, cs = 0, cy = 0, sy = 0;
        for (std::size_t i = 0; i < trace.size(); ++i) {
          const double y = trace.position_mm[i] - from.prediction_mm[i];
          const double c = std::cos(kTwoPi * f * (trace.t_s[i] - t_mid));
          const double s = std::sin(kTwoPi * f * (trace.t_s[i] - t_mid));
          cc += c * c;
          ss += s * s;
          cs += c * s;
          cy += c * y;
          sy += s * y;
        }
        const double det = cc * ss - cs * cs;
        if (!(det > 0.0)) continue;
        const double rc = (ss * cy - cs * sy) / det;
        const double rs = (cc * sy - cs * cy) / det;
        const double gain = rc * cy + rs * sy;  // residual sum of squares removed
        if (gain > best) {
          best = gain;
          p[static_cast<std::size_t>(b.resp)] = rc;
          p[static_cast<std::size_t>(b.resp + 1)] = rs;
          p[static_cast<std::size_t>(b.resp + 2)] = f;
        }
      }
    }
  }
  return p;
}

}  // namespace echoservo::lab

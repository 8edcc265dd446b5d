// Motion terms beyond the catalog: a term's value (mm) is ADDED to the heartbeat model's
// position (lab/motion_model.h), or its value (rad) is added to the heartbeat's phase; its
// parameters are fitted with the rest of the model.
//
// File terms: `heartbeat:2+@path/term.json` reads an effect file (hw/effect_file.h, the
// project's format) that defines one or both hooks
//   position_mm(time_s, cardiac_phase_rad, heart_rate_hz, heartbeat_mm)   [mm]
//   phase_rad(time_s)                                                     [rad]
// with time_s the time since the trace's first sample (s), cardiac_phase_rad the fitted
// heartbeat's phase φ wrapped to [0, 2π) (the harmonics are a_k cos kφ + b_k sin kφ; φ = 0
// at the middle of the trace; phase terms included), heart_rate_hz the rate of the
// heartbeat's constant-rate (+ rate_drift) phase (Hz; phase terms not included) and
// heartbeat_mm the harmonics' sum Σ a_k cos kφ + b_k sin kφ at that phase (mm, without the
// offset). phase_rad is added to φ before the harmonics are evaluated (a timing change).
// The expression may use those inputs and the file's parameters (name, unit, start value,
// bounds). Files written before phase_rad and heartbeat_mm existed read unchanged.
// Library terms: the building blocks the motion lab's discovery (lab/motion_diagnosis.h)
// selects from, evaluated natively (automatic derivatives) and written as an effect file
// for the proposal (t = time_s, T a fitted period, H = heartbeat_mm):
//   baseline_linear      s·t              s = slope_mm_s (mm/s)
//   baseline_quadratic   c·t²             c = curvature_mm_s2 (mm/s²)
//   amplitude_growth<k>  (g_c cos kφ + g_s sin kφ)·t   harmonic k's amplitude changes
//                        linearly in time (g in mm/s), k = 1..the model's harmonics.
//   baseline_step        a/(1 + exp(−(t − t0)/w))   a jump of a = step_mm (mm) at
//                        t0 = step_time_s (s, within the trace), rise width w =
//                        step_width_s (s, ≥ one sample period, ≤ 1 s).
//   baseline_sine        c·cos(2πt/T) + s·sin(2πt/T)   a slow periodic baseline of unknown
//                        period (sine_cos_mm, sine_sin_mm in mm; T = sine_period_s).
//   amplitude_modulation H·(m_c cos(2πt/T) + m_s sin(2πt/T))   the beat scaled by
//                        1 + m·sin(2πt/T + ψ), m = |(m_c, m_s)| (modulation_cos,
//                        modulation_sin dimensionless; T = modulation_period_s).
//   rate_modulation      phase += T·(r_c sin(2πt/T) − r_s cos(2πt/T))   the instantaneous
//                        heart rate f0 + r_c cos(2πt/T) + r_s sin(2πt/T) (rate_cos_hz,
//                        rate_sin_hz in Hz; swing Δf = |(r_c, r_s)|; T = rate_period_s).
//   beat_timing          phase += δφ(t), piecewise linear between knots every ~1.5 beats
//                        (timing<j>_rad at knot j, rad); fitted with a penalty on its second
//                        differences (and a weak one on its values) that a file cannot carry:
//                        refitted from the file it is unpenalised.
// Bounds: periods between a few beats and 2/3 of the trace's duration (MotionTermContext:
// 1.5 cycles within the trace, else a trend term is the better description), amplitudes
// within physical limits (±100 mm, |m| ≤ 0.9, ±0.5 Hz, ±10 rad).
// Errors: std::invalid_argument-derived errors naming the file, key and why.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace echoservo::hw {
class Expression;
}

namespace echoservo::lab {

enum class MotionTermKind {
  kFile,
  kBaselineLinear,
  kBaselineQuadratic,
  kAmplitudeGrowth,
  kBaselineStep,
  kBaselineSine,
  kAmplitudeModulation,
  kRateModulation,
  kBeatTiming,
};

struct MotionTerm {
  MotionTermKind kind = MotionTermKind::kFile;
  int harmonic = 0;  // kAmplitudeGrowth: k
  std::string name;  // library name, or the effect file's name
  std::string path;  // file terms: the path as written after '@'
  std::vector<std::string> parameters;
  std::vector<std::string> units;
  std::vector<double> start;
  std::vector<double> lower;
  std::vector<double> upper;
  std::string expression;        // the position_mm expression ("" when the term has none)
  std::string phase_expression;  // the phase_rad expression ("" when the term has none)
  std::string equation;          // in words, with units
  // kBeatTiming: knot j at time_s = j·knot_spacing_s.
  double knot_spacing_s = 0.0;
  // Penalised knots (any kind; a file cannot carry it, discovery sets it on the file term
  // it cross-validates): parameters [penalty_first, penalty_first + penalty_knots) get
  // penalty·(second difference) and 0.05·penalty·(value) as residuals (in noise σ).
  // MotionTermLibrary sets it on beat_timing (all its parameters).
  double penalty = 0.0;
  std::size_t penalty_first = 0;
  std::size_t penalty_knots = 0;
};

// What the library's bounds and start values are scaled to.
struct MotionTermContext {
  double duration_s = 30.0;       // last − first sample time
  double sample_period_s = 0.04;  // median sampling interval
  double rate_hz = 1.2;           // the trace's heart rate
};

// The inputs of the position_mm hook: time_s, cardiac_phase_rad, heart_rate_hz,
// heartbeat_mm.
std::vector<std::string> MotionTermInputs();
// The inputs of the phase_rad hook: time_s.
std::vector<std::string> MotionPhaseInputs();

// Reads a motion-term effect file. Throws std::invalid_argument naming the file, the key
// and why (neither hook position_mm nor phase_rad, unknown variable, bad bounds, …).
MotionTerm ReadMotionTerm(const std::filesystem::path& path);

// Writes `terms` (library or file terms) as one effect file named `name` whose position_mm
// is the sum of their position expressions and whose phase_rad is the sum of their phase
// expressions (a hook only when some term has it); the parameters' defaults are the terms'
// start values. `signature` says where its residual shows. Creates the parent folder.
void WriteMotionTermFile(const std::filesystem::path& path, const std::string& name,
                         const std::string& signature, const std::vector<MotionTerm>& terms);

// The discovery library for a model with `harmonics` harmonics, bounds scaled to `context`.
std::vector<MotionTerm> MotionTermLibrary(int harmonics, const MotionTermContext& context = {});

// Evaluates one file term; not shared between threads (one per fit).
class MotionTermEvaluator {
 public:
  explicit MotionTermEvaluator(const MotionTerm& term);
  ~MotionTermEvaluator();
  MotionTermEvaluator(MotionTermEvaluator&&) noexcept;
  MotionTermEvaluator& operator=(MotionTermEvaluator&&) noexcept;
  // position_mm at the inputs with `parameters` (the term's, in its order); 0 without the
  // hook.
  double operator()(double time_s, double phase_rad, double rate_hz, double heartbeat_mm,
                    const double* parameters) const;
  // phase_rad at time_s; 0 without the hook.
  double Phase(double time_s, const double* parameters) const;
  bool has_position() const { return expression_ != nullptr; }
  bool has_phase() const { return phase_ != nullptr; }

 private:
  std::unique_ptr<hw::Expression> expression_;
  std::unique_ptr<hw::Expression> phase_;
  mutable std::vector<double> values_;
  mutable std::vector<double> phase_values_;
};

}  // namespace echoservo::lab

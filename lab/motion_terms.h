// Motion terms beyond the catalog: a term's value (mm) is ADDED to the heartbeat model's
// position (lab/motion_model.h) and its parameters are fitted with the rest of the model.
//
// File terms: `heartbeat:2+@path/term.json` reads an effect file (hw/effect_file.h, the
// project's format) that defines the hook
//   position_mm(time_s, cardiac_phase_rad, heart_rate_hz)   [mm]
// with time_s the time since the trace's first sample (s), cardiac_phase_rad the fitted
// heartbeat's phase φ wrapped to [0, 2π) (the harmonics are a_k cos kφ + b_k sin kφ; φ = 0
// at the middle of the trace) and heart_rate_hz the fitted instantaneous rate (Hz). The
// expression may use those inputs and the file's parameters (name, unit, start value,
// bounds).
// Library terms: the building blocks the motion lab's discovery (lab/motion_diagnosis.h)
// selects from, evaluated natively (automatic derivatives) and written as an effect file
// for the proposal:
//   baseline_linear      s·t              s = slope_mm_s (mm/s)
//   baseline_quadratic   c·t²             c = curvature_mm_s2 (mm/s²)
//   amplitude_growth<k>  (g_c cos kφ + g_s sin kφ)·t   harmonic k's amplitude changes
//                        linearly in time (g in mm/s), k = 1..the model's harmonics.
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

enum class MotionTermKind { kFile, kBaselineLinear, kBaselineQuadratic, kAmplitudeGrowth };

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
  std::string expression;  // the position_mm expression (file terms; library: its text)
  std::string equation;    // in words, with units
};

// The hook table of motion-term files: position_mm(time_s, cardiac_phase_rad,
// heart_rate_hz).
std::vector<std::string> MotionTermInputs();

// Reads a motion-term effect file. Throws std::invalid_argument naming the file, the key
// and why (missing hook position_mm, unknown variable, bad bounds, …).
MotionTerm ReadMotionTerm(const std::filesystem::path& path);

// Writes `terms` (library or file terms) as one effect file named `name` whose position_mm
// is their sum; `signature` says where its residual shows. Creates the parent folder.
void WriteMotionTermFile(const std::filesystem::path& path, const std::string& name,
                         const std::string& signature, const std::vector<MotionTerm>& terms);

// The discovery library for a model with `harmonics` harmonics.
std::vector<MotionTerm> MotionTermLibrary(int harmonics);

// Evaluates one file term; not shared between threads (one per fit).
class MotionTermEvaluator {
 public:
  explicit MotionTermEvaluator(const MotionTerm& term);
  ~MotionTermEvaluator();
  MotionTermEvaluator(MotionTermEvaluator&&) noexcept;
  MotionTermEvaluator& operator=(MotionTermEvaluator&&) noexcept;
  // position_mm at the inputs with `parameters` (the term's, in its order).
  double operator()(double time_s, double phase_rad, double rate_hz,
                    const double* parameters) const;

 private:
  std::unique_ptr<hw::Expression> expression_;
  mutable std::vector<double> values_;
};

}  // namespace echoservo::lab

// `echoservo sim motion`: writes a synthetic target-motion trace (predict's CSV format).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <stdexcept>

#include "apps/commands/motion_commands.h"
#include "control/experiments/synthetic_motion.h"

namespace echoservo::apps {
namespace {

struct SimMotionFlags {
  control::SyntheticMotionOptions o = control::MitralHrvDefaults();
  std::string out;
};

void Write(const SimMotionFlags& f) {
  const control::SyntheticMotion m = control::MakeSyntheticMotion(f.o);
  std::ofstream out(f.out, std::ios::trunc);
  if (!out) throw std::runtime_error("sim motion: cannot write " + f.out);
  out << "t,position,truth,heart_rate_bpm\n";
  char line[128];
  for (std::size_t i = 0; i < m.measured.size(); ++i) {
    std::snprintf(line, sizeof line, "%.6f,%.4f,%.4f,%.3f\n", m.measured.t_s[i],
                  m.measured.position_mm[i], m.truth_mm[i], m.heart_rate_bpm[i]);
    out << line;
  }
  out.close();
  if (!out) throw std::runtime_error("sim motion: error writing " + f.out);
  std::cout << "wrote " << f.out << ": " << m.measured.size() << " samples over " << f.o.duration_s
            << " s (columns t, position = truth + noise, truth, heart_rate_bpm)\n";
}

}  // namespace

void AddSimMotion(CLI::App* sim) {
  auto f = std::make_shared<SimMotionFlags>();
  auto* cmd = sim->add_subcommand(
      "motion",
      "Write a synthetic mitral-annulus motion trace with heart-rate variability, "
      "respiration and noise (CSV for `predict` and `lab`)");
  cmd->add_option("--out", f->out, "CSV file to write")->required();
  cmd->add_option("--duration", f->o.duration_s, "Seconds (default 40)");
  cmd->add_option("--sample-rate", f->o.sample_rate_hz, "Samples per second (default 250)");
  cmd->add_option("--bpm", f->o.heart_rate_bpm, "Mean heart rate (default 72)");
  cmd->add_option("--p2p", f->o.peak_to_peak_mm, "Peak-to-peak motion, mm (default 12)");
  cmd->add_option("--harmonics", f->o.harmonics, "Harmonics of the mitral shape (default 10)");
  cmd->add_option("--rsa", f->o.rsa_bpm, "Respiratory sinus arrhythmia amplitude, bpm (default 3)");
  cmd->add_option("--wander", f->o.wander_bpm, "Random heart-rate wander sigma, bpm (default 3)");
  cmd->add_option("--wander-tau", f->o.wander_tau_s,
                  "Correlation time of the wander, s (default 8)");
  cmd->add_option("--drift", f->o.rate_drift_bpm_per_min,
                  "Linear heart-rate drift, bpm per minute (default 0)");
  cmd->add_option("--respiration", f->o.respiration_mm,
                  "Respiratory displacement amplitude, mm (default 0)");
  cmd->add_option("--respiration-hz", f->o.respiration_hz, "Breathing rate, Hz (default 0.25)");
  cmd->add_option("--noise", f->o.noise_mm, "Measurement noise sigma, mm (default 0.3)");
  cmd->add_option("--seed", f->o.seed, "Random seed (default 1)");
  cmd->callback([f] { Write(*f); });
}

}  // namespace echoservo::apps

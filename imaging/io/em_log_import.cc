#include "imaging/io/em_log_import.h"

#include <algorithm>
#include <map>
#include <set>
#include <stdexcept>

namespace echoservo::imaging {
namespace {

namespace fs = std::filesystem;

constexpr std::string_view kSuffix = "Transform";

std::string FrameWhere(const fs::path& source, std::size_t frame) {
  return source.string() + ": frame " + std::to_string(frame);
}

std::string ToolList(const PlusSequence& sequence, const std::vector<std::string>& tools) {
  std::string s;
  for (const std::string& tool : tools) {
    const auto ok = std::count_if(sequence.frames.begin(), sequence.frames.end(),
                                  [&](const SequenceFrame& f) { return f.TransformValid(tool); });
    s += (s.empty() ? "" : ", ") + tool + " (" + std::to_string(ok) + " OK)";
  }
  return s;
}

}  // namespace

std::vector<std::string> PlusTrackerTools(const PlusSequence& sequence) {
  std::set<std::string> tools;
  for (const SequenceFrame& frame : sequence.frames) {
    for (const auto& [name, value] : frame.fields) {
      if (name.size() > kSuffix.size() && name.ends_with(kSuffix)) {
        tools.insert(name.substr(0, name.size() - kSuffix.size()));
      }
    }
  }
  return {tools.begin(), tools.end()};
}

formats::EmLog PlusSequenceToEmLog(const PlusSequence& sequence, const fs::path& source,
                                   const formats::EmImportOptions& options) {
  formats::EmLog log;
  log.source = source;
  log.format = formats::EmLogFormat::kPlus;
  log.sensors = PlusTrackerTools(sequence);
  if (log.sensors.empty()) {
    throw std::invalid_argument(source.string() +
                                ": no tracked tool (no Seq_FrameNNNN_<Tool>Transform field)");
  }
  std::string tool = options.sensor;
  if (tool.ends_with(kSuffix) && tool.size() > kSuffix.size()) {
    tool.resize(tool.size() - kSuffix.size());
  }
  if (tool.empty()) {
    if (log.sensors.size() != 1) {
      throw std::invalid_argument(
          source.string() + ": " + std::to_string(log.sensors.size()) +
          " tracked tools; choose one with --sensor: " + ToolList(sequence, log.sensors));
    }
    tool = log.sensors.front();
  } else if (std::find(log.sensors.begin(), log.sensors.end(), tool) == log.sensors.end()) {
    throw std::invalid_argument(source.string() + ": no tool '" + options.sensor +
                                "' (--sensor); the tools are " + ToolList(sequence, log.sensors));
  }
  log.sensor = tool;
  formats::EmLogAppender append(log, formats::ResolveUnits(source, options, std::nullopt));
  for (std::size_t i = 0; i < sequence.frames.size(); ++i) {
    const SequenceFrame& frame = sequence.frames[i];
    const std::string where = FrameWhere(source, i);
    std::optional<double> t_s;
    try {
      t_s = frame.Timestamp();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(where + ": " + e.what());
    }
    if (!t_s) throw std::invalid_argument(where + ": no Timestamp or UnfilteredTimestamp field");
    const std::optional<std::string> status = frame.TransformStatus(tool);
    if (!status || *status != "OK") {
      append.AddDropout(*t_s, status ? *status : std::string("absent"), where);
      continue;
    }
    std::optional<Eigen::Matrix4d> m;
    try {
      m = frame.Transform(tool);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(where + ": " + e.what());
    }
    if (!m) {  // a status OK without the transform itself
      append.AddDropout(*t_s, "absent", where);
      continue;
    }
    append.AddValid(*t_s, m->block<3, 1>(0, 3), where);
  }
  return log;
}

formats::EmLog ReadPlusEmLog(const fs::path& path, const formats::EmImportOptions& options) {
  return PlusSequenceToEmLog(ReadPlusSequence(path), path, options);
}

formats::EmLog ReadEmLog(const fs::path& path, const formats::EmImportOptions& options) {
  const formats::EmLogFormat format = options.format == formats::EmLogFormat::kAuto
                                          ? formats::DetectEmLogFormat(path)
                                          : options.format;
  switch (format) {
    case formats::EmLogFormat::kPlus:
      return ReadPlusEmLog(path, options);
    case formats::EmLogFormat::kAurora:
      return formats::ReadAuroraEmLog(path, options);
    case formats::EmLogFormat::kSim:
    case formats::EmLogFormat::kAuto:
      break;
  }
  return formats::ReadSimEmLog(path, options);
}

}  // namespace echoservo::imaging

#include "imaging/io/recording.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "imaging/io/plus_sequence.h"
#include "imaging/io/sequence_reader.h"
#include "imaging/io/truth_fields.h"
#include "imaging/io/volume_io.h"

namespace echoservo::imaging {
namespace fs = std::filesystem;

namespace {

// Frames read one at a time (sequence_reader.h): memory holds one volume, whatever the
// recording's length.
class SequenceSource : public VolumeSource {
 public:
  explicit SequenceSource(std::unique_ptr<SequenceReader> reader) : reader_(std::move(reader)) {
    const auto& frames = reader_->sequence().frames;
    const auto n = frames.size();
    if (n >= 2) {
      const auto t0 = frames.front().Timestamp();
      const auto t1 = frames.back().Timestamp();
      if (t0 && t1 && *t1 > *t0) rate_hz_ = static_cast<double>(n - 1) / (*t1 - *t0);
    }
  }
  std::optional<SourceFrame> Next() override {
    if (next_ >= reader_->size()) return std::nullopt;
    const std::size_t i = next_++;
    return SourceFrame{reader_->ReadVolume(i),
                       TruthFromFields(reader_->sequence().frames[i].fields)};
  }
  double nominal_rate_hz() const override { return rate_hz_; }

 private:
  std::unique_ptr<SequenceReader> reader_;
  std::size_t next_ = 0;
  double rate_hz_ = 0.0;
};

class FileListSource : public VolumeSource {
 public:
  explicit FileListSource(std::vector<fs::path> files) : files_(std::move(files)) {}
  std::optional<SourceFrame> Next() override {
    if (next_ >= files_.size()) return std::nullopt;
    Volume v = ReadVolume(files_[next_]);
    v.set_frame_index(static_cast<std::int64_t>(next_));
    ++next_;
    return SourceFrame{std::move(v), std::nullopt};
  }
  double nominal_rate_hz() const override { return 0.0; }

 private:
  std::vector<fs::path> files_;
  std::size_t next_ = 0;
};

}  // namespace

bool IsPlusSequenceFile(const fs::path& path) {
  std::string name = path.filename().string();
  for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char* suffix : {".igs.mha", ".igs.mhd", ".igs.nrrd"}) {
    const std::string s = suffix;
    if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0)
      return true;
  }
  return false;
}

std::unique_ptr<VolumeSource> OpenRecording(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(path, ec)) {
      if (entry.is_regular_file(ec) && IsVolumeFile(entry.path()) &&
          !IsPlusSequenceFile(entry.path())) {
        files.push_back(entry.path());
      }
    }
    if (ec)
      throw std::invalid_argument(path.string() + ": cannot list the folder: " + ec.message());
    if (files.empty()) {
      throw std::invalid_argument(path.string() +
                                  ": folder holds no volume files (.mha, .mhd, .vti, .nrrd)");
    }
    std::sort(files.begin(), files.end());
    return std::make_unique<FileListSource>(std::move(files));
  }
  if (!fs::exists(path, ec))
    throw std::invalid_argument(path.string() + ": no such file or folder");
  if (IsPlusSequenceFile(path)) {
    auto reader = std::make_unique<SequenceReader>(path);
    const PlusSequence& seq = reader->sequence();
    if (seq.FrameBytes() == 0) {
      throw std::invalid_argument(
          path.string() + ": tracker-only sequence (no images) cannot be replayed as volumes");
    }
    if (seq.element_type != "MET_UCHAR") {
      throw std::invalid_argument(path.string() + ": ElementType " + seq.element_type +
                                  " is not supported (volumes must be MET_UCHAR)");
    }
    return std::make_unique<SequenceSource>(std::move(reader));
  }
  if (!IsVolumeFile(path)) {
    throw std::invalid_argument(path.string() +
                                ": not a recording (expected a .mha/.mhd/.vti/.nrrd volume, an "
                                ".igs.mha/.igs.nrrd sequence, or a folder of volumes)");
  }
  return std::make_unique<FileListSource>(std::vector<fs::path>{path});
}

}  // namespace echoservo::imaging

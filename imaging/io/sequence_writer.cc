#include "imaging/io/sequence_writer.h"

#include <stdexcept>
#include <utility>

#include "formats/durable_file.h"
#include "imaging/io/plus_sequence.h"

namespace echoservo::imaging {
namespace fs = std::filesystem;

struct SequenceWriter::State {
  PlusSequence sequence;  // header and frame fields; no pixels
  VolumeGeometry geometry;
  formats::AppendOnlyFile voxels;
  bool broken = false;  // an I/O error left the data file's length unknown
};

SequenceWriter::SequenceWriter(fs::path header_path) : header_path_(std::move(header_path)) {
  if (header_path_.extension() != ".mhd" || header_path_.stem().empty()) {
    throw std::invalid_argument(
        header_path_.string() +
        ": a streamed sequence is a MetaImage header with its data beside it; "
        "name it <name>.mhd (e.g. volumes.igs.mhd)");
  }
}

SequenceWriter::~SequenceWriter() = default;

fs::path SequenceWriter::data_path() const {
  fs::path p = header_path_;
  return p.replace_extension(".raw");
}

std::size_t SequenceWriter::frames() const { return state_ ? state_->sequence.frames.size() : 0; }

void SequenceWriter::Append(const Volume& volume,
                            const std::map<std::string, std::string>& extra_fields) {
  if (!state_) {
    auto s = std::make_unique<State>();
    s->sequence = SequenceFor(volume);
    s->geometry = volume.geometry();
    s->voxels = formats::AppendOnlyFile(data_path());
    state_ = std::move(s);
  } else if (state_->broken) {
    throw std::runtime_error(data_path().string() +
                             ": an earlier write failed; the recording stops at frame " +
                             std::to_string(frames()));
  } else if (!(volume.geometry() == state_->geometry)) {
    throw std::invalid_argument(
        header_path_.string() + ": frame " + std::to_string(frames()) +
        " has a geometry different from frame 0's (a sequence holds one geometry)");
  }
  SequenceFrame frame = VolumeFrameFields(volume);
  for (const auto& [k, v] : extra_fields) frame.fields[k] = v;
  std::vector<SequenceFrame>& frames = state_->sequence.frames;
  frames.push_back(std::move(frame));
  std::string header;
  try {
    header = PlusSequenceDetachedHeader(state_->sequence, data_path().filename().string());
  } catch (...) {
    frames.pop_back();  // a field that cannot be written: the frame is not recorded
    throw;
  }
  try {
    state_->voxels.Append(volume.voxels().data(), volume.voxels().size());
    formats::ReplaceFileContents(header_path_, header);
  } catch (...) {
    frames.pop_back();
    state_->broken = true;
    throw;
  }
}

void SequenceWriter::SyncData() {
  if (state_) state_->voxels.SyncData();
}

}  // namespace echoservo::imaging

// Fuzz target: PLUS sequence metafiles and the MetaImage/NRRD text-header parser under them
// (imaging/io/plus_sequence.h, imaging/io/metaio_internal.h).
//
// The input is written to a scratch `.igs.mha` file (the reader picks MetaImage or NRRD by
// content) and read with ReadPlusSequence; an accepted sequence then goes through every
// per-frame helper (transforms, statuses, timestamps) and SequenceToVolumes, as `info`,
// `detect` and `report` use it; and the frame-at-a-time SequenceReader (as `track --replay`
// uses it) must give the same frames, voxel for voxel, or refuse the same ones. Only
// std::invalid_argument may escape.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>

#include "imaging/io/plus_sequence.h"
#include "imaging/io/sequence_reader.h"
#include "tests/fuzz/fuzz_util.h"

namespace img = echoservo::imaging;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto& path = echoservo::fuzz::Scratch().Write(".igs.mha", {data, size});
  img::PlusSequence sequence;
  try {
    sequence = img::ReadPlusSequence(path);
  } catch (const std::invalid_argument&) {
    return 0;
  }
  if (sequence.pixels.size() != sequence.frames.size() * sequence.FrameBytes()) __builtin_trap();
  for (std::size_t f = 0; f < sequence.frames.size(); ++f) {
    const img::SequenceFrame& frame = sequence.frames[f];
    (void)sequence.FramePixels(f);
    for (const auto& [name, value] : frame.fields) {
      try {
        (void)frame.Transform(name);
        (void)frame.TransformStatus(name);
        (void)frame.TransformValid(name);
      } catch (const std::invalid_argument&) {
      }
    }
    try {
      (void)frame.Timestamp();
      (void)frame.ImageStatus();
    } catch (const std::invalid_argument&) {
    }
  }
  (void)sequence.FrameFieldNames();
  try {
    (void)img::SequenceToVolumes(sequence);
  } catch (const std::invalid_argument&) {
  }
  try {
    img::SequenceReader reader(path);
    if (reader.size() != sequence.frames.size()) __builtin_trap();
    for (std::size_t f = 0; f < reader.size(); ++f) {
      std::optional<img::Volume> whole, streamed;
      try {
        whole = img::SequenceFrameToVolume(sequence, f);
      } catch (const std::invalid_argument&) {
      }
      try {
        streamed = reader.ReadVolume(f);
      } catch (const std::invalid_argument&) {
      }
      if (whole.has_value() != streamed.has_value()) __builtin_trap();
      if (whole && !std::ranges::equal(whole->voxels(), streamed->voxels())) __builtin_trap();
    }
  } catch (const std::invalid_argument&) {
  }
  return 0;
}

// Fuzz target: single-volume files (imaging/io/volume_io.h): MetaImage (.mha, header parsed
// and checked by our code, raw pixels then read by VTK's MetaIO, compressed ones by our
// inflate) and NRRD (decoded by our code). The first input byte picks the syntax (even:
// .mha, odd: .nrrd), the rest is the file. InspectVolumeFile and ReadVolume must reject a
// bad file with std::invalid_argument before VTK allocates anything. (.vti is VTK's own XML
// parser, out of scope.)
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>

#include "imaging/io/volume_io.h"
#include "tests/fuzz/fuzz_util.h"

namespace img = echoservo::imaging;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const char* ext = (data[0] & 1) ? ".nrrd" : ".mha";
  const auto& path = echoservo::fuzz::Scratch().Write(ext, {data + 1, size - 1});
  try {
    (void)img::InspectVolumeFile(path);
    const img::Volume v = img::ReadVolume(path);
    const auto& d = v.dims();
    if (v.voxel_count() != static_cast<std::size_t>(d.x()) * d.y() * d.z()) __builtin_trap();
    volatile unsigned sum = 0;
    for (std::uint8_t x : v.voxels()) sum = sum + x;
  } catch (const std::invalid_argument&) {
  }
  return 0;
}

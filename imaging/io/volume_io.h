// Reading and writing single 3D volumes: MetaImage (.mha, .mhd + .raw/.zraw), VTK XML image
// data (.vti) and NRRD (.nrrd, .nhdr; read only).
//
// Units and frames as in imaging/volume.h: spacing and origin in mm, `direction` columns
// the index axes in the image frame. Poses, timestamp and frame index are not stored in
// these files: read volumes get identity poses and time 0 (plus_sequence.h carries them).
// Only uint8 single-component data makes a Volume; headers are checked (4 GiB cap, sizes
// against the file) before VTK or anything else allocates.
// Errors: std::invalid_argument naming the file and the problem (another scalar type, a
// corrupt or lying header, an unknown extension, a failed write).
// Details: docs/imaging.md#volume-files-imagingiovolume_ioh
#pragma once

#include <filesystem>
#include <string>

#include "imaging/volume.h"

namespace echoservo::imaging {

// By extension (case-insensitive): .mha, .mhd, .vti, .nrrd, .nhdr.
Volume ReadVolume(const std::filesystem::path& path);

struct WriteVolumeOptions {
  bool compress = true;  // zlib for MetaImage (CompressedData = True) and VTI (appended data)
};
// By extension: .mha (data in the file), .mhd (data in a .raw or, compressed, .zraw next to
// it), .vti. Throws std::invalid_argument for another extension or when writing fails.
void WriteVolume(const Volume& volume, const std::filesystem::path& path,
                 const WriteVolumeOptions& options = {});

// What a volume file declares, from its header alone (no pixel data read), for `info`.
struct VolumeFileInfo {
  std::string format;        // "MetaImage", "NRRD", "VTI"
  std::string element_type;  // MetaImage spelling (MET_UCHAR, ...); VTI: VTK type name
  bool compressed = false;
};
VolumeFileInfo InspectVolumeFile(const std::filesystem::path& path);

// True when the extension is one ReadVolume accepts.
bool IsVolumeFile(const std::filesystem::path& path);

}  // namespace echoservo::imaging

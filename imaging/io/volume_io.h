// Reading and writing single 3D volumes: MetaImage (.mha, .mhd + .raw/.zraw), VTK XML image
// data (.vti) and NRRD (.nrrd, read only; VTK has no NRRD writer).
//
// Units and frames as in imaging/volume.h: spacing and origin in mm, `direction` columns are
// the index axes in the image frame. Geometry on disk:
//   MetaImage  ElementSpacing, Offset, TransformMatrix (9 numbers: the direction's columns
//              one after the other — ITK's convention, column c = numbers 3c..3c+2).
//   VTI        Spacing, Origin, Direction (VTK 9 attribute, row-major).
//   NRRD       space directions (index axis vectors = direction column · spacing), space
//              origin.
// Pixel data: vtkXMLImageDataReader (.vti, geometry incl. Direction from VTK) and
// vtkMetaImageReader (raw MetaImage); writing: vtkMetaImageWriter, vtkXMLImageDataWriter.
// Exceptions, each because VTK 9.1 falls short here: (a) MetaImage geometry comes from our
// own parse of the text header (VTK's reader drops TransformMatrix), and WriteVolume rewrites
// the header VTK wrote with exact ElementSpacing, Offset and TransformMatrix (VTK writes an
// identity matrix and rounded numbers); (b) compressed MetaImage pixel data is inflated by
// our checked zlib code (VTK's MetaIO returns garbage silently for a corrupt stream);
// (c) NRRD is decoded by our code (vtkNrrdReader cannot read gzip encoding and drops the
// direction). Pose (image_to_probe,
// probe_to_reference), timestamp and frame index are not stored in these files (see
// plus_sequence.h for files that carry them); read volumes get identity poses and time 0.
//
// Only uint8 single-component scalars make a Volume: any other scalar type is an error that
// names the type (no silent rescaling). Before VTK sees a MetaImage or NRRD file its header
// is parsed and checked: the declared sizes must describe a valid VolumeGeometry, fit the
// 4 GiB cap, and agree with the bytes in the file (raw) or be possible from them (compressed),
// so a corrupt header never makes VTK allocate. A .vti file's WholeExtent is checked the
// same way. Errors: std::invalid_argument naming the file and the problem.
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

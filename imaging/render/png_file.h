// 8-bit RGB PNG files for the render panels and their tests, written and read with VTK's
// PNG writer/reader (vtkIOImage, which the volume readers already load), so that the
// imaging library does not need OpenCV's imgcodecs and the ~100 shared libraries it brings
// (GDAL, HDF5, MPI, …) into every process that links it.
//
// Pixels are stored row-major with the top row first, three bytes (R, G, B) per pixel —
// the order image viewers show; VTK's bottom-up row order stays inside png_file.cc.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

namespace echoservo::imaging {

struct RgbImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;  // width · height · 3 bytes, top row first

  // Pixel (x right, y down) channel c (0 R, 1 G, 2 B); asserted in range.
  std::uint8_t At(int x, int y, int c) const;
};

// Writes `image` to `png` (the parent folder must exist). Throws std::invalid_argument when
// the buffer does not match width · height · 3, std::runtime_error when the file cannot be
// written.
void WritePngRgb(const std::filesystem::path& png, const RgbImage& image);

// Reads an 8-bit PNG as RGB (grey is replicated, alpha dropped). Throws std::runtime_error
// naming the file when it is missing or not a readable 8-bit PNG.
RgbImage ReadPngRgb(const std::filesystem::path& png);

}  // namespace echoservo::imaging

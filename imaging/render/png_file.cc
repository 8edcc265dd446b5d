#include "imaging/render/png_file.h"

#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>
#include <vtkPNGWriter.h>
#include <vtkPointData.h>
#include <vtkUnsignedCharArray.h>

#include <cassert>
#include <cstring>
#include <stdexcept>
#include <string>

namespace echoservo::imaging {

std::uint8_t RgbImage::At(int x, int y, int c) const {
  assert(x >= 0 && x < width && y >= 0 && y < height && c >= 0 && c < 3);
  return rgb[(static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
              static_cast<std::size_t>(x)) *
                 3 +
             static_cast<std::size_t>(c)];
}

void WritePngRgb(const std::filesystem::path& png, const RgbImage& image) {
  const auto w = static_cast<std::size_t>(image.width);
  const auto h = static_cast<std::size_t>(image.height);
  if (image.width <= 0 || image.height <= 0 || image.rgb.size() != w * h * 3) {
    throw std::invalid_argument("PNG " + png.string() + ": " + std::to_string(image.rgb.size()) +
                                " bytes for a " + std::to_string(image.width) + "×" +
                                std::to_string(image.height) + " RGB image");
  }
  vtkNew<vtkImageData> data;
  data->SetDimensions(image.width, image.height, 1);
  data->AllocateScalars(VTK_UNSIGNED_CHAR, 3);
  auto* out = static_cast<std::uint8_t*>(data->GetScalarPointer());
  for (std::size_t y = 0; y < h; ++y) {  // VTK's first row is the bottom one
    std::memcpy(out + (h - 1 - y) * w * 3, image.rgb.data() + y * w * 3, w * 3);
  }
  vtkNew<vtkPNGWriter> writer;
  writer->SetFileName(png.string().c_str());
  writer->SetInputData(data);
  writer->Write();
  if (writer->GetErrorCode() != 0 || !std::filesystem::exists(png)) {
    throw std::runtime_error("cannot write " + png.string());
  }
}

RgbImage ReadPngRgb(const std::filesystem::path& png) {
  if (!std::filesystem::is_regular_file(png)) {
    throw std::runtime_error("cannot read " + png.string() + ": no such file");
  }
  vtkNew<vtkPNGReader> reader;
  if (reader->CanReadFile(png.string().c_str()) == 0) {
    throw std::runtime_error("cannot read " + png.string() + ": not a PNG file");
  }
  reader->SetFileName(png.string().c_str());
  reader->Update();
  vtkImageData* data = reader->GetOutput();
  const int* dims = data->GetDimensions();
  const int channels = data->GetNumberOfScalarComponents();
  if (reader->GetErrorCode() != 0 || data->GetScalarType() != VTK_UNSIGNED_CHAR || dims[0] <= 0 ||
      dims[1] <= 0 || dims[2] != 1 || channels < 1 || channels > 4) {
    throw std::runtime_error("cannot read " + png.string() + ": not an 8-bit 2D PNG image");
  }
  RgbImage image;
  image.width = dims[0];
  image.height = dims[1];
  const auto w = static_cast<std::size_t>(image.width);
  const auto h = static_cast<std::size_t>(image.height);
  const auto n = static_cast<std::size_t>(channels);
  image.rgb.resize(w * h * 3);
  const auto* in = static_cast<const std::uint8_t*>(data->GetScalarPointer());
  for (std::size_t y = 0; y < h; ++y) {
    const std::uint8_t* row = in + (h - 1 - y) * w * n;
    for (std::size_t x = 0; x < w; ++x) {
      for (std::size_t c = 0; c < 3; ++c) {
        // Grey (1) and grey + alpha (2) replicate the grey value; RGBA drops alpha.
        image.rgb[(y * w + x) * 3 + c] = row[x * n + (n < 3 ? 0 : c)];
      }
    }
  }
  return image;
}

}  // namespace echoservo::imaging

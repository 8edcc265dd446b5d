#include "imaging/io/volume_io.h"

#include <vtkCommand.h>
#include <vtkImageData.h>
#include <vtkMatrix3x3.h>
#include <vtkMetaImageReader.h>
#include <vtkMetaImageWriter.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>
#include <vtkUnsignedCharArray.h>
#include <vtkXMLImageDataReader.h>
#include <vtkXMLImageDataWriter.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "imaging/io/metaio_internal.h"

namespace echoservo::imaging {
namespace fs = std::filesystem;
namespace ii = io_internal;

namespace {

std::string LowerExtension(const fs::path& path) {
  std::string e = path.extension().string();
  for (auto& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

[[noreturn]] void Fail(const fs::path& path, const std::string& what) {
  throw std::invalid_argument(path.string() + ": " + what);
}

// Collects VTK errors raised by an algorithm instead of printing them.
class ErrorObserver : public vtkCommand {
 public:
  static ErrorObserver* New() { return new ErrorObserver; }
  void Execute(vtkObject*, unsigned long event, void* data) override {
    if (event == vtkCommand::ErrorEvent && data != nullptr) {
      if (!message.empty()) message += "; ";
      message += static_cast<const char*>(data);
    }
  }
  std::string message;
};

std::string TrimVtkMessage(std::string m) {
  // VTK messages start with "ERROR: In <source file>, line N\n<class> (0x...): text".
  if (const auto p = m.find("): "); p != std::string::npos) m = m.substr(p + 3);
  while (!m.empty() && std::isspace(static_cast<unsigned char>(m.back()))) m.pop_back();
  return m;
}

// uint8 single-component image data → Volume with the given geometry (dims must agree).
Volume ToVolume(vtkImageData* image, const VolumeGeometry& geometry, const fs::path& path) {
  if (image == nullptr || image->GetPointData()->GetScalars() == nullptr) {
    Fail(path, "the reader produced no image scalars");
  }
  if (image->GetScalarType() != VTK_UNSIGNED_CHAR) {
    Fail(path, std::string("scalar type ") + image->GetScalarTypeAsString() +
                   " is not supported (volumes must be unsigned char / uint8)");
  }
  if (image->GetNumberOfScalarComponents() != 1) {
    Fail(path, std::to_string(image->GetNumberOfScalarComponents()) +
                   "-component scalars are not supported (volumes have one)");
  }
  int d[3];
  image->GetDimensions(d);
  if (d[0] != geometry.dims.x() || d[1] != geometry.dims.y() || d[2] != geometry.dims.z()) {
    Fail(path, "the reader produced dims that differ from the header's");
  }
  Volume v = Volume::Create(geometry);
  const auto* src = static_cast<const std::uint8_t*>(image->GetScalarPointer());
  auto dst = v.voxels();
  if (image->GetPointData()->GetScalars()->GetNumberOfValues() !=
      static_cast<vtkIdType>(dst.size())) {
    Fail(path, "the reader produced a wrong number of voxels");
  }
  std::memcpy(dst.data(), src, dst.size());
  return v;
}

VolumeGeometry GeometryFromMetaHeader(const ii::TextHeader& h, const ii::PixelLayout& L) {
  const std::string where = h.Where();
  if (L.dims.size() < 2 || L.dims.size() > 3) {
    Fail(h.path, "NDims = " + std::to_string(L.dims.size()) + " (a volume has 2 or 3)");
  }
  const std::size_t n = L.dims.size();
  VolumeGeometry g;
  for (std::size_t a = 0; a < n; ++a) {
    if (L.dims[a] < 1 || L.dims[a] > VolumeGeometry::kMaxDim) {
      Fail(h.path, "DimSize = " + h.Require("DimSize") + ": each size must be in [1, " +
                       std::to_string(VolumeGeometry::kMaxDim) + "]");
    }
    g.dims[static_cast<int>(a)] = static_cast<int>(L.dims[a]);
  }
  auto vec = [&](const char* key, std::size_t count) -> std::optional<std::vector<double>> {
    auto v = h.Find(key);
    if (!v) return std::nullopt;
    auto nums = ii::ParseNumbers(*v, where + key);
    if (nums.size() != count) {
      Fail(h.path, std::string(key) + " has " + std::to_string(nums.size()) +
                       " numbers, expected " + std::to_string(count));
    }
    return nums;
  };
  auto spacing = vec("ElementSpacing", n);
  if (!spacing) spacing = vec("ElementSize", n);
  if (spacing)
    for (std::size_t a = 0; a < n; ++a) g.spacing_mm[static_cast<int>(a)] = (*spacing)[a];
  auto origin = vec("Offset", n);
  if (!origin) origin = vec("Origin", n);
  if (!origin) origin = vec("Position", n);
  if (origin)
    for (std::size_t a = 0; a < n; ++a) g.origin_mm[static_cast<int>(a)] = (*origin)[a];
  auto tm = vec("TransformMatrix", n * n);
  if (!tm) tm = vec("Rotation", n * n);
  if (!tm) tm = vec("Orientation", n * n);
  if (tm) {
    for (std::size_t c = 0; c < n; ++c)
      for (std::size_t r = 0; r < n; ++r)
        g.direction(static_cast<int>(r), static_cast<int>(c)) = (*tm)[c * n + r];
  }
  g.Validate(h.path.string());
  return g;
}

VolumeGeometry GeometryFromNrrd(const ii::TextHeader& h, const ii::PixelLayout& L) {
  if (L.dims.size() < 2 || L.dims.size() > 3) {
    Fail(h.path, "dimension: " + std::to_string(L.dims.size()) + " (a volume has 2 or 3)");
  }
  VolumeGeometry g;
  for (std::size_t a = 0; a < L.dims.size(); ++a) {
    if (L.dims[a] < 1 || L.dims[a] > VolumeGeometry::kMaxDim) {
      Fail(h.path,
           "sizes: each size must be in [1, " + std::to_string(VolumeGeometry::kMaxDim) + "]");
    }
    g.dims[static_cast<int>(a)] = static_cast<int>(L.dims[a]);
  }
  if (!L.nrrd_space_directions.empty()) {
    for (std::size_t a = 0; a < L.dims.size(); ++a) {
      const auto& v = L.nrrd_space_directions[a];
      if (v.empty()) Fail(h.path, "space directions: axis " + std::to_string(a) + " is 'none'");
      if (v.size() > 3) Fail(h.path, "space directions: more than 3 components");
      Eigen::Vector3d col = Eigen::Vector3d::Zero();
      for (std::size_t r = 0; r < v.size(); ++r) col[static_cast<int>(r)] = v[r];
      const double s = col.norm();
      if (!(s > 0))
        Fail(h.path, "space directions: axis " + std::to_string(a) + " has zero length");
      g.spacing_mm[static_cast<int>(a)] = s;
      g.direction.col(static_cast<int>(a)) = col / s;
    }
  } else if (auto sp = h.Find("spacings")) {
    auto s = ii::ParseNumbers(*sp, h.Where() + "spacings");
    for (std::size_t a = 0; a < std::min<std::size_t>(s.size(), 3); ++a)
      g.spacing_mm[static_cast<int>(a)] = s[a];
  }
  for (std::size_t r = 0; r < std::min<std::size_t>(L.nrrd_space_origin.size(), 3); ++r) {
    g.origin_mm[static_cast<int>(r)] = L.nrrd_space_origin[r];
  }
  g.Validate(h.path.string());
  return g;
}

// A .vti header: the start of the file, checked for a sane WholeExtent before VTK parses it.
VolumeGeometry CheckVtiHeader(const fs::path& path, std::uint64_t file_size) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail(path, "cannot open for reading");
  std::string head(static_cast<std::size_t>(std::min<std::uint64_t>(file_size, 1 << 16)), '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  if (head.find("<VTKFile") == std::string::npos || head.find("ImageData") == std::string::npos) {
    Fail(path, "not a VTK XML ImageData file (no <VTKFile type=\"ImageData\">)");
  }
  const auto p = head.find("WholeExtent=\"");
  if (p == std::string::npos) Fail(path, "no WholeExtent in the ImageData element");
  const auto q = head.find('"', p + 13);
  if (q == std::string::npos) Fail(path, "unterminated WholeExtent");
  const auto e = ii::ParseNumbers(head.substr(p + 13, q - p - 13), path.string() + ": WholeExtent");
  if (e.size() != 6) Fail(path, "WholeExtent needs 6 numbers");
  VolumeGeometry g;
  for (int a = 0; a < 3; ++a) {
    const double n = e[2 * a + 1] - e[2 * a] + 1;
    if (!(n >= 1 && n <= VolumeGeometry::kMaxDim)) {
      Fail(path, "WholeExtent gives " + std::to_string(static_cast<long long>(n)) +
                     " voxels on axis " + std::to_string(a) + ", outside [1, " +
                     std::to_string(VolumeGeometry::kMaxDim) + "]");
    }
    g.dims[a] = static_cast<int>(n);
  }
  g.Validate(path.string());
  const bool compressed = head.find("compressor=") != std::string::npos;
  const auto voxels = static_cast<std::uint64_t>(g.VoxelCount());
  if (!compressed && voxels > file_size) {
    Fail(path, "WholeExtent declares " + std::to_string(voxels) + " voxels but the file has only " +
                   std::to_string(file_size) + " bytes");
  }
  if (compressed && voxels > file_size * ii::kMaxDeflateRatio + 4096) {
    Fail(path, "WholeExtent declares more voxels than the compressed file can hold");
  }
  return g;
}

Volume ReadVti(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    Fail(path, fs::exists(path, ec) ? "not a regular file" : "no such file");
  const auto size = fs::file_size(path, ec);
  CheckVtiHeader(path, size);
  vtkNew<vtkXMLImageDataReader> reader;
  vtkNew<ErrorObserver> errors;
  reader->AddObserver(vtkCommand::ErrorEvent, errors);
  reader->SetFileName(path.string().c_str());
  reader->Update();
  vtkImageData* image = reader->GetOutput();
  if (!errors->message.empty() || reader->GetErrorCode() != 0) {
    Fail(path, "VTK could not read it: " +
                   (errors->message.empty()
                        ? std::string("error code ") + std::to_string(reader->GetErrorCode())
                        : TrimVtkMessage(errors->message)));
  }
  if (image == nullptr) Fail(path, "VTK produced no image");
  VolumeGeometry g;
  int d[3];
  image->GetDimensions(d);
  g.dims = Eigen::Vector3i(d[0], d[1], d[2]);
  double s[3], o[3];
  image->GetSpacing(s);
  image->GetOrigin(o);
  g.spacing_mm = Eigen::Vector3d(s[0], s[1], s[2]);
  // VTK's origin is the physical point of index (0,0,0) of the *extent*; our volumes start
  // at index 0, so fold a non-zero extent start into the origin.
  int ext[6];
  image->GetExtent(ext);
  vtkMatrix3x3* m = image->GetDirectionMatrix();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) g.direction(r, c) = m->GetElement(r, c);
  g.origin_mm = Eigen::Vector3d(o[0], o[1], o[2]) +
                g.direction * Eigen::Vector3d(ext[0] * s[0], ext[2] * s[1], ext[4] * s[2]);
  g.Validate(path.string());
  return ToVolume(image, g, path);
}

Volume ReadMeta(const fs::path& path) {
  const auto h = ii::ReadTextHeader(path);
  if (h.syntax != ii::HeaderSyntax::kMetaImage) Fail(path, "is a NRRD file, not MetaImage");
  const auto L = ii::CheckPixelLayout(h);
  if (L.element_type != "MET_UCHAR") {
    Fail(path, "ElementType = " + L.element_type + " is not supported (volumes must be MET_UCHAR)");
  }
  const VolumeGeometry g = GeometryFromMetaHeader(h, L);
  if (L.compressed) {
    // VTK 9.1's MetaIO inflates without reporting a corrupt or short zlib stream (it hands
    // back garbage silently), so compressed pixel data is decoded by our checked inflater.
    const auto pixels = ii::ReadPixels(h, L);
    Volume v = Volume::Create(g);
    std::copy(pixels.begin(), pixels.end(), v.voxels().begin());
    return v;
  }
  vtkNew<vtkMetaImageReader> reader;
  vtkNew<ErrorObserver> errors;
  reader->AddObserver(vtkCommand::ErrorEvent, errors);
  reader->SetFileName(path.string().c_str());
  reader->Update();
  if (!errors->message.empty() || reader->GetErrorCode() != 0) {
    Fail(path, "VTK could not read it: " +
                   (errors->message.empty()
                        ? std::string("error code ") + std::to_string(reader->GetErrorCode())
                        : TrimVtkMessage(errors->message)));
  }
  return ToVolume(reader->GetOutput(), g, path);
}

// NRRD: parsed and decoded here (vtkNrrdReader 9.1 cannot read gzip encoding and drops the
// direction), with the same header checks as MetaImage.
Volume ReadNrrd(const fs::path& path) {
  const auto h = ii::ReadTextHeader(path);
  if (h.syntax != ii::HeaderSyntax::kNrrd) Fail(path, "is not a NRRD file (no NRRD magic)");
  const auto L = ii::CheckPixelLayout(h);
  if (L.element_type != "MET_UCHAR") {
    Fail(path, "type: " + h.Require("type") + " is not supported (volumes must be uint8)");
  }
  const VolumeGeometry g = GeometryFromNrrd(h, L);
  const auto pixels = ii::ReadPixels(h, L);
  Volume v = Volume::Create(g);
  std::copy(pixels.begin(), pixels.end(), v.voxels().begin());
  return v;
}

vtkSmartPointer<vtkImageData> ToImageData(const Volume& v) {
  auto image = vtkSmartPointer<vtkImageData>::New();
  image->SetDimensions(v.dims().x(), v.dims().y(), v.dims().z());
  image->SetSpacing(v.spacing_mm().data());
  image->SetOrigin(v.origin_mm().data());
  double m[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m[3 * r + c] = v.direction()(r, c);
  image->SetDirectionMatrix(m);
  image->AllocateScalars(VTK_UNSIGNED_CHAR, 1);
  std::memcpy(image->GetScalarPointer(), v.voxels().data(), v.voxels().size());
  return image;
}

// Rewrites ElementSpacing, Offset and TransformMatrix of a MetaImage file VTK wrote, with
// exact numbers, keeping the pixel data.
void PatchMetaHeader(const fs::path& path, const Volume& v) {
  const auto h = ii::ReadTextHeader(path);
  auto nums = [](auto begin, auto end) {
    std::string s;
    for (auto it = begin; it != end; ++it) {
      if (!s.empty()) s += ' ';
      s += ii::FormatNumber(*it);
    }
    return s;
  };
  std::vector<double> tm;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) tm.push_back(v.direction()(r, c));
  const std::string spacing = nums(v.spacing_mm().data(), v.spacing_mm().data() + 3);
  const std::string origin = nums(v.origin_mm().data(), v.origin_mm().data() + 3);
  const std::string transform = nums(tm.begin(), tm.end());
  std::string text;
  bool have_tm = false;
  for (const auto& e : h.entries) {
    std::string value = e.value;
    if (e.key == "ElementSpacing") value = spacing;
    if (e.key == "Offset" || e.key == "Position" || e.key == "Origin") value = origin;
    if (e.key == "TransformMatrix") {
      value = transform;
      have_tm = true;
    }
    if (e.key == "ElementDataFile" && !have_tm) text += "TransformMatrix = " + transform + "\n";
    text += e.key + " = " + value + "\n";
  }
  std::string data;
  if (h.data_path == path) {
    std::ifstream in(path, std::ios::binary);
    in.seekg(static_cast<std::streamoff>(h.data_offset));
    data.resize(static_cast<std::size_t>(h.data_available));
    in.read(data.data(), static_cast<std::streamsize>(data.size()));
  }
  const fs::path tmp = path.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text << data;
    if (!out) Fail(path, "cannot write");
  }
  fs::rename(tmp, path);
}

}  // namespace

bool IsVolumeFile(const fs::path& path) {
  const auto e = LowerExtension(path);
  return e == ".mha" || e == ".mhd" || e == ".vti" || e == ".nrrd" || e == ".nhdr";
}

Volume ReadVolume(const fs::path& path) {
  const auto e = LowerExtension(path);
  if (e == ".mha" || e == ".mhd") return ReadMeta(path);
  if (e == ".vti") return ReadVti(path);
  if (e == ".nrrd" || e == ".nhdr") return ReadNrrd(path);
  Fail(path, "unknown volume file extension '" + path.extension().string() +
                 "' (expected .mha, .mhd, .vti, .nrrd)");
}

void WriteVolume(const Volume& volume, const fs::path& path, const WriteVolumeOptions& options) {
  const auto e = LowerExtension(path);
  auto image = ToImageData(volume);
  vtkNew<ErrorObserver> errors;
  if (e == ".mha" || e == ".mhd") {
    vtkNew<vtkMetaImageWriter> writer;
    writer->AddObserver(vtkCommand::ErrorEvent, errors);
    writer->SetInputData(image);
    writer->SetFileName(path.string().c_str());
    std::string raw;
    if (e == ".mhd") {
      raw = fs::path(path).replace_extension(options.compress ? ".zraw" : ".raw").string();
      writer->SetRAWFileName(raw.c_str());
    }
    writer->SetCompression(options.compress);
    writer->Write();
    if (!errors->message.empty() || writer->GetErrorCode() != 0) {
      Fail(path, "VTK could not write it: " + TrimVtkMessage(errors->message));
    }
    PatchMetaHeader(path, volume);
  } else if (e == ".vti") {
    vtkNew<vtkXMLImageDataWriter> writer;
    writer->AddObserver(vtkCommand::ErrorEvent, errors);
    writer->SetInputData(image);
    writer->SetFileName(path.string().c_str());
    writer->SetDataModeToAppended();
    writer->EncodeAppendedDataOff();
    if (options.compress) {
      writer->SetCompressorTypeToZLib();
    } else {
      writer->SetCompressorTypeToNone();
    }
    if (writer->Write() != 1 || !errors->message.empty()) {
      Fail(path, "VTK could not write it: " + TrimVtkMessage(errors->message));
    }
  } else {
    Fail(path, "cannot write volumes with extension '" + path.extension().string() +
                   "' (use .mha, .mhd or .vti)");
  }
}

VolumeFileInfo InspectVolumeFile(const fs::path& path) {
  const auto e = LowerExtension(path);
  VolumeFileInfo info;
  if (e == ".vti") {
    const Volume v = ReadVti(path);  // small enough; validates the file too
    info.format = "VTI";
    info.element_type = "MET_UCHAR";
    std::ifstream in(path, std::ios::binary);
    std::string head(4096, '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    info.compressed = head.find("compressor=") != std::string::npos;
    return info;
  }
  const auto h = ii::ReadTextHeader(path);
  const auto L = ii::CheckPixelLayout(h);
  info.format = h.syntax == ii::HeaderSyntax::kNrrd ? "NRRD" : "MetaImage";
  info.element_type = L.element_type;
  info.compressed = L.compressed;
  return info;
}

}  // namespace echoservo::imaging

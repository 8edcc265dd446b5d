#include "imaging/io/plus_sequence.h"

#include <algorithm>
#include <cassert>
#include <cctype>
#include <fstream>
#include <set>
#include <stdexcept>

#include "imaging/io/metaio_internal.h"
#include "imaging/io/plus_sequence_internal.h"

namespace echoservo::imaging {
namespace fs = std::filesystem;
namespace ii = io_internal;

namespace {

constexpr const char* kFramePrefix = "Seq_Frame";

std::string WithTransformSuffix(const std::string& name) {
  const std::string suffix = "Transform";
  if (name.size() >= suffix.size() &&
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
    return name;
  }
  return name + suffix;
}

bool IsStructuralMetaKey(const std::string& k) {
  static const std::set<std::string> keys = {"ObjectType",
                                             "NDims",
                                             "BinaryData",
                                             "BinaryDataByteOrderMSB",
                                             "ElementByteOrderMSB",
                                             "CompressedData",
                                             "CompressedDataSize",
                                             "DimSize",
                                             "ElementSpacing",
                                             "ElementSize",
                                             "ElementType",
                                             "Offset",
                                             "Origin",
                                             "Position",
                                             "TransformMatrix",
                                             "Rotation",
                                             "Orientation",
                                             "ElementDataFile",
                                             "ElementNumberOfChannels",
                                             "HeaderSize"};
  return keys.count(k) != 0;
}

// "ultrasound image orientation" → "UltrasoundImageOrientation" (NRRD key/values → MetaImage keys).
std::string CamelCase(const std::string& key) {
  if (key.find(' ') == std::string::npos) return key;
  std::string out;
  bool up = true;
  for (char c : key) {
    if (c == ' ') {
      up = true;
      continue;
    }
    out += up ? static_cast<char>(std::toupper(static_cast<unsigned char>(c))) : c;
    up = false;
  }
  return out;
}

std::string JoinNumbers(const std::vector<double>& v) {
  std::string s;
  for (double x : v) {
    if (!s.empty()) s += ' ';
    s += ii::FormatNumber(x);
  }
  return s;
}

std::string NrrdType(const std::string& met) {
  if (met == "MET_UCHAR") return "uint8";
  if (met == "MET_CHAR") return "int8";
  if (met == "MET_USHORT") return "uint16";
  if (met == "MET_SHORT") return "int16";
  if (met == "MET_UINT") return "uint32";
  if (met == "MET_INT") return "int32";
  if (met == "MET_FLOAT") return "float";
  if (met == "MET_DOUBLE") return "double";
  throw std::invalid_argument("PLUS sequence: element type " + met + " cannot be written to NRRD");
}

}  // namespace

std::optional<std::string> SequenceFrame::Field(const std::string& name) const {
  const auto it = fields.find(name);
  if (it == fields.end()) return std::nullopt;
  return it->second;
}

std::optional<Eigen::Matrix4d> SequenceFrame::Transform(const std::string& name) const {
  const std::string key = WithTransformSuffix(name);
  const auto v = Field(key);
  if (!v) return std::nullopt;
  const auto n = ii::ParseNumbers(*v, key);
  if (n.size() != 16) {
    throw std::invalid_argument(key + ": expected 16 numbers, got " + std::to_string(n.size()));
  }
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = n[static_cast<std::size_t>(4 * r + c)];
  return m;
}

std::optional<std::string> SequenceFrame::TransformStatus(const std::string& name) const {
  const std::string key = WithTransformSuffix(name);
  if (auto s = Field(key + "Status")) return ii::Trim(*s);
  if (Field(key)) return std::string("OK");
  return std::nullopt;
}

bool SequenceFrame::TransformValid(const std::string& name) const {
  const auto s = TransformStatus(name);
  return s && *s == "OK";
}

std::optional<double> SequenceFrame::Timestamp() const {
  for (const char* key : {"Timestamp", "UnfilteredTimestamp"}) {
    if (auto v = Field(key)) {
      const auto n = ii::ParseNumbers(*v, key);
      if (n.size() != 1) throw std::invalid_argument(std::string(key) + ": expected one number");
      return n[0];
    }
  }
  return std::nullopt;
}

std::optional<std::string> SequenceFrame::ImageStatus() const { return Field("ImageStatus"); }

std::uint64_t PlusSequence::FrameBytes() const {
  std::uint64_t n = static_cast<std::uint64_t>(element_size);
  for (int d : frame_dims) n *= static_cast<std::uint64_t>(std::max(d, 0));
  return n;
}

std::span<const std::uint8_t> PlusSequence::FramePixels(std::size_t frame) const {
  assert(frame < frames.size());
  const auto b = FrameBytes();
  assert(pixels.size() >= (frame + 1) * b);
  return std::span<const std::uint8_t>(pixels).subspan(frame * b, b);
}

std::span<std::uint8_t> PlusSequence::FramePixels(std::size_t frame) {
  assert(frame < frames.size());
  const auto b = FrameBytes();
  assert(pixels.size() >= (frame + 1) * b);
  return std::span<std::uint8_t>(pixels).subspan(frame * b, b);
}

std::vector<std::string> PlusSequence::FrameFieldNames() const {
  std::set<std::string> names;
  for (const auto& f : frames)
    for (const auto& [k, v] : f.fields) names.insert(k);
  return {names.begin(), names.end()};
}

std::optional<std::string> PlusSequence::HeaderField(const std::string& key) const {
  for (const auto& [k, v] : header_fields)
    if (k == key) return v;
  return std::nullopt;
}

namespace io_internal {

SequenceHeader ReadSequenceHeader(const fs::path& path, std::uint64_t max_pixel_bytes) {
  SequenceHeader out;
  out.text = ReadTextHeader(path);
  out.layout = CheckPixelLayout(out.text, max_pixel_bytes);
  const TextHeader& h = out.text;
  const PixelLayout& L = out.layout;
  const std::string where = h.Where();
  const bool nrrd = h.syntax == ii::HeaderSyntax::kNrrd;
  const std::size_t nd = L.dims.size();
  if (nd != 3 && nd != 4) {
    throw std::invalid_argument(where + (nrrd ? "dimension " : "NDims ") + std::to_string(nd) +
                                ": a sequence has 3 (2D frames) or 4 (3D frames) axes");
  }
  PlusSequence& s = out.sequence;
  s.volume_frames = nd == 4;
  s.element_type = L.element_type;
  s.element_size = L.element_size;
  s.compressed = L.compressed;
  for (std::size_t a = 0; a + 1 < nd; ++a) {
    if (L.dims[a] > VolumeGeometry::kMaxDim * 4LL) {
      throw std::invalid_argument(where + "frame size " + std::to_string(L.dims[a]) +
                                  " is too large");
    }
    s.frame_dims[a] = static_cast<int>(L.dims[a]);
  }
  if (nd == 3) s.frame_dims[2] = s.frame_dims[0] == 0 && s.frame_dims[1] == 0 ? 0 : 1;
  const std::int64_t n_frames = L.dims.back();
  if (static_cast<std::uint64_t>(n_frames) > kMaxSequenceFrames) {
    throw std::invalid_argument(where + "declares " + std::to_string(n_frames) +
                                " frames, more than the " + std::to_string(kMaxSequenceFrames) +
                                " a sequence may have");
  }
  const bool tracker_only = s.FrameBytes() == 0;
  if (tracker_only && static_cast<std::uint64_t>(n_frames) > h.entries.size()) {
    throw std::invalid_argument(where + "declares " + std::to_string(n_frames) +
                                " frames without pixels but has only " +
                                std::to_string(h.entries.size()) + " header fields");
  }
  if (tracker_only && L.element_size > 0 && s.frame_dims[0] * s.frame_dims[1] != 0) {
    throw std::invalid_argument(where + "inconsistent frame size");
  }
  s.frames.resize(static_cast<std::size_t>(n_frames));  // bounded by pixels or fields
  if (tracker_only) {  // no pixels: the element type means nothing (NRRD cannot say MET_OTHER)
    s.element_type = "MET_OTHER";
    s.element_size = 0;
  }

  // Geometry of one frame.
  const std::size_t spatial = std::min<std::size_t>(nd, 3);
  if (!nrrd) {
    auto vec = [&](const char* key, std::size_t count) -> std::optional<std::vector<double>> {
      auto v = h.Find(key);
      if (!v) return std::nullopt;
      auto nums = ParseNumbers(*v, where + key);
      if (nums.size() != count) {
        throw std::invalid_argument(where + key + " has " + std::to_string(nums.size()) +
                                    " numbers, NDims = " + std::to_string(nd) + " needs " +
                                    std::to_string(count));
      }
      return nums;
    };
    if (auto sp = vec("ElementSpacing", nd))
      for (std::size_t a = 0; a < spatial; ++a) s.spacing_mm[static_cast<int>(a)] = (*sp)[a];
    if (auto o = vec("Offset", nd))
      for (std::size_t a = 0; a < spatial; ++a) s.origin_mm[static_cast<int>(a)] = (*o)[a];
    if (auto tm = vec("TransformMatrix", nd * nd))
      for (std::size_t c = 0; c < spatial; ++c)
        for (std::size_t r = 0; r < spatial; ++r)
          s.direction(static_cast<int>(r), static_cast<int>(c)) = (*tm)[c * nd + r];
  } else {
    if (!L.nrrd_space_directions.empty()) {
      for (std::size_t a = 0; a + 1 < nd; ++a) {
        const auto& v = L.nrrd_space_directions[a];
        if (v.empty() || v.size() > 3) {
          throw std::invalid_argument(where + "space directions: frame axis " + std::to_string(a) +
                                      " must be a vector of 2 or 3 numbers");
        }
        Eigen::Vector3d col = Eigen::Vector3d::Zero();
        for (std::size_t r = 0; r < v.size(); ++r) col[static_cast<int>(r)] = v[r];
        const double len = col.norm();
        if (!(len > 0)) throw std::invalid_argument(where + "space directions: zero-length axis");
        s.spacing_mm[static_cast<int>(a)] = len;
        s.direction.col(static_cast<int>(a)) = col / len;
      }
      if (nd == 3) s.direction.col(2) = s.direction.col(0).cross(s.direction.col(1)).normalized();
    }
    for (std::size_t r = 0; r < std::min<std::size_t>(L.nrrd_space_origin.size(), 3); ++r) {
      s.origin_mm[static_cast<int>(r)] = L.nrrd_space_origin[r];
    }
  }

  // Header and frame fields.
  for (const auto& e : h.entries) {
    if (e.key.rfind(kFramePrefix, 0) == 0) {
      std::size_t p = std::char_traits<char>::length(kFramePrefix);
      const std::size_t digits_begin = p;
      while (p < e.key.size() && std::isdigit(static_cast<unsigned char>(e.key[p]))) ++p;
      if (p == digits_begin || p >= e.key.size() || e.key[p] != '_' || p + 1 == e.key.size() ||
          p - digits_begin > 12) {
        throw std::invalid_argument(where + "malformed frame field name '" + e.key + "'");
      }
      const auto index = ParseInteger(e.key.substr(digits_begin, p - digits_begin), where + e.key);
      if (index >= n_frames) {
        throw std::invalid_argument(where + e.key + ": frame " + std::to_string(index) +
                                    " but the sizes declare " + std::to_string(n_frames) +
                                    " frames");
      }
      std::string name = e.key.substr(p + 1);
      if (nrrd && name == "Status") name = "ImageStatus";
      s.frames[static_cast<std::size_t>(index)].fields[name] = e.value;
      continue;
    }
    if (nrrd) {
      if (e.nrrd_keyvalue) s.header_fields.emplace_back(CamelCase(e.key), e.value);
    } else if (!IsStructuralMetaKey(e.key)) {
      s.header_fields.emplace_back(e.key, e.value);
    }
  }
  return out;
}

}  // namespace io_internal

PlusSequence ReadPlusSequence(const fs::path& path) {
  ii::SequenceHeader h = ii::ReadSequenceHeader(path, ii::kMaxPixelBytes);
  if (h.layout.pixel_bytes > 0) h.sequence.pixels = ii::ReadPixels(h.text, h.layout);
  return std::move(h.sequence);
}

namespace {

std::string DimsText(const PlusSequence& s, std::size_t n_frames) {
  std::vector<std::int64_t> dims = {s.frame_dims[0], s.frame_dims[1]};
  if (s.volume_frames) dims.push_back(s.frame_dims[2]);
  dims.push_back(static_cast<std::int64_t>(n_frames));
  std::string text;
  for (auto d : dims) {
    if (!text.empty()) text += ' ';
    text += std::to_string(d);
  }
  return text;
}

std::string DefaultKinds(const PlusSequence& s) {
  return s.volume_frames ? "domain domain domain list" : "domain domain list";
}

// Seq_FrameNNNN_<name>, with 4 digits (more when the sequence has more than 10000 frames).
std::string FrameKey(std::size_t i, std::size_t n_frames, const std::string& name) {
  std::size_t width = 4;
  for (std::size_t n = n_frames; n > 10000; n /= 10) ++width;
  std::string num = std::to_string(i);
  if (num.size() < width) num.insert(0, width - num.size(), '0');
  return std::string(kFramePrefix) + num + "_" + name;
}

void CheckFrameFields(const PlusSequence& s, const std::string& where) {
  for (const auto& f : s.frames) {
    for (const auto& [k, v] : f.fields) {
      if (k.empty() || v.find('\n') != std::string::npos ||
          k.find_first_of(" =:\n") != std::string::npos) {
        throw std::invalid_argument(
            where + "frame field '" + k +
            "' cannot be written (empty name, or newline/space/'='/':' in it)");
      }
    }
  }
}

// The MetaImage header of `s`, up to and including its ElementDataFile line (`data_file`:
// LOCAL, or the name of the raw file beside the header). `compressed_size`: the size of the
// zlib stream when the data are compressed.
std::string MetaHeaderText(const PlusSequence& s, std::optional<std::size_t> compressed_size,
                           const std::string& data_file, const std::string& where) {
  const std::size_t nd = s.volume_frames ? 4 : 3;
  const std::size_t n_frames = s.frames.size();
  std::string text;
  auto line = [&](const std::string& k, const std::string& v) { text += k + " = " + v + "\n"; };
  std::vector<double> spacing, offset, tm;
  for (std::size_t a = 0; a < nd; ++a) {
    spacing.push_back(a < 3 ? s.spacing_mm[static_cast<int>(a)] : 1.0);
    offset.push_back(a < 3 ? s.origin_mm[static_cast<int>(a)] : 0.0);
  }
  for (std::size_t c = 0; c < nd; ++c)
    for (std::size_t r = 0; r < nd; ++r)
      tm.push_back(r < 3 && c < 3 ? s.direction(static_cast<int>(r), static_cast<int>(c))
                                  : (r == c ? 1.0 : 0.0));
  line("ObjectType", "Image");
  line("NDims", std::to_string(nd));
  line("AnatomicalOrientation", s.HeaderField("AnatomicalOrientation").value_or("RAI"));
  line("BinaryData", "True");
  line("BinaryDataByteOrderMSB", "False");
  line("CenterOfRotation",
       s.HeaderField("CenterOfRotation").value_or(nd == 4 ? "0 0 0 0" : "0 0 0"));
  line("CompressedData", compressed_size ? "True" : "False");
  if (compressed_size) line("CompressedDataSize", std::to_string(*compressed_size));
  line("DimSize", DimsText(s, n_frames));
  line("Kinds", s.HeaderField("Kinds").value_or(DefaultKinds(s)));
  line("ElementSpacing", JoinNumbers(spacing));
  line("ElementType", s.element_type);
  line("Offset", JoinNumbers(offset));
  line("TransformMatrix", JoinNumbers(tm));
  for (const auto& [k, v] : s.header_fields) {
    if (k == "AnatomicalOrientation" || k == "CenterOfRotation" || k == "Kinds" ||
        IsStructuralMetaKey(k))
      continue;
    if (k.empty() || k.find('=') != std::string::npos || k.rfind(kFramePrefix, 0) == 0) {
      throw std::invalid_argument(where + "header field name '" + k + "' cannot be written");
    }
    line(k, v);
  }
  for (std::size_t i = 0; i < n_frames; ++i)
    for (const auto& [k, v] : s.frames[i].fields) line(FrameKey(i, n_frames, k), v);
  line("ElementDataFile", data_file);
  return text;
}

std::string NrrdHeaderText(const PlusSequence& s, bool compressed, const std::string& where) {
  const std::size_t nd = s.volume_frames ? 4 : 3;
  const std::size_t n_frames = s.frames.size();
  std::string text =
      "NRRD0004\n# Complete NRRD file format specification at:\n"
      "# http://teem.sourceforge.net/nrrd/format.html\n";
  text += "dimension: " + std::to_string(nd) + "\n";
  text += std::string("encoding: ") + (compressed ? "gz" : "raw") + "\n";
  text += "endian: little\n";
  text += "kinds: " + DefaultKinds(s) + "\n";
  text += "sizes: " + DimsText(s, n_frames) + "\n";
  text += "space dimension: 3\n";
  std::string dirs;
  for (std::size_t a = 0; a + 1 < nd; ++a) {
    const Eigen::Vector3d v =
        s.direction.col(static_cast<int>(a)) * s.spacing_mm[static_cast<int>(a)];
    dirs += '(';
    dirs += ii::FormatNumber(v.x());
    dirs += ',';
    dirs += ii::FormatNumber(v.y());
    dirs += ',';
    dirs += ii::FormatNumber(v.z());
    dirs += ") ";
  }
  text += "space directions: " + dirs + "none\n";
  text += "space origin: (";
  text += ii::FormatNumber(s.origin_mm.x());
  text += ',';
  text += ii::FormatNumber(s.origin_mm.y());
  text += ',';
  text += ii::FormatNumber(s.origin_mm.z());
  text += ")\n";
  text += "type: " + NrrdType(s.element_type == "MET_OTHER" ? "MET_UCHAR" : s.element_type) + "\n";
  for (const auto& [k, v] : s.header_fields) {
    if (k.find(":=") != std::string::npos || k.rfind(kFramePrefix, 0) == 0) {
      throw std::invalid_argument(where + "header field name '" + k + "' cannot be written");
    }
    text += k + ":=" + v + "\n";
  }
  for (std::size_t i = 0; i < n_frames; ++i)
    for (const auto& [k, v] : s.frames[i].fields)
      text += FrameKey(i, n_frames, k == "ImageStatus" ? "Status" : k) + ":=" + v + "\n";
  text += "\n";
  return text;
}

void CheckElementType(const PlusSequence& s, const std::string& where) {
  if (ii::MetaElementSize(s.element_type).value_or(-1) != s.element_size && s.FrameBytes() > 0) {
    throw std::invalid_argument(where + "element_size " + std::to_string(s.element_size) +
                                " does not match element_type " + s.element_type);
  }
}

}  // namespace

void WritePlusSequence(const PlusSequence& s, const fs::path& path, bool compress) {
  const std::string where = path.string() + ": ";
  const auto expected = s.FrameBytes() * s.frames.size();
  if (s.pixels.size() != expected) {
    throw std::invalid_argument(where + "pixels has " + std::to_string(s.pixels.size()) +
                                " bytes, frames × frame size is " + std::to_string(expected));
  }
  CheckElementType(s, where);
  CheckFrameFields(s, where);
  const bool nrrd = [&] {
    std::string e = path.extension().string();
    for (auto& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return e == ".nrrd";
  }();
  std::vector<std::uint8_t> packed;
  const bool do_compress = compress && !s.pixels.empty();
  if (do_compress) packed = ii::Deflate(s.pixels, nrrd);
  const std::string text =
      nrrd ? NrrdHeaderText(s, do_compress, where)
           : MetaHeaderText(s,
                            do_compress ? std::optional<std::size_t>(packed.size()) : std::nullopt,
                            "LOCAL", where);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw std::invalid_argument(where + "cannot open for writing");
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  const auto& data = do_compress ? packed : s.pixels;
  out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
  out.close();
  if (!out) throw std::invalid_argument(where + "write failed");
}

std::string PlusSequenceDetachedHeader(const PlusSequence& s, const std::string& data_file_name) {
  const std::string where = "PLUS sequence header for " + data_file_name + ": ";
  if (data_file_name.empty() || data_file_name == "LOCAL" || data_file_name == "LIST" ||
      data_file_name.find_first_of(" %/\n") != std::string::npos) {
    throw std::invalid_argument(where + "not a plain file name");
  }
  CheckElementType(s, where);
  CheckFrameFields(s, where);
  return MetaHeaderText(s, std::nullopt, data_file_name, where);
}

Volume SequenceFrameToVolume(const PlusSequence& s, std::size_t frame) {
  if (frame < s.frames.size() && s.pixels.size() >= (frame + 1) * s.FrameBytes())
    return SequenceFrameToVolume(s, frame, s.FramePixels(frame));
  return SequenceFrameToVolume(s, frame, {});  // the checks there name what is wrong
}

Volume SequenceFrameToVolume(const PlusSequence& s, std::size_t frame,
                             std::span<const std::uint8_t> pixels) {
  const std::string where = "PLUS sequence frame " + std::to_string(frame) + ": ";
  if (frame >= s.frames.size()) throw std::invalid_argument(where + "no such frame");
  if (s.element_type != "MET_UCHAR" || s.element_size != 1) {
    throw std::invalid_argument(where + "ElementType " + s.element_type + " is not MET_UCHAR");
  }
  if (s.FrameBytes() == 0)
    throw std::invalid_argument(where + "tracker-only sequence has no images");
  if (pixels.size() != s.FrameBytes()) {
    throw std::invalid_argument(where + std::to_string(pixels.size()) +
                                " bytes of pixels, the frame has " +
                                std::to_string(s.FrameBytes()));
  }
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(s.frame_dims[0], s.frame_dims[1], s.frame_dims[2]);
  g.spacing_mm = s.spacing_mm;
  g.origin_mm = s.origin_mm;
  g.direction = s.direction;
  Volume v = Volume::Create(g);
  std::copy(pixels.begin(), pixels.end(), v.voxels().begin());
  const auto& f = s.frames[frame];
  v.set_frame_index(static_cast<std::int64_t>(frame));
  try {
    if (auto n = f.Field("FrameNumber")) v.set_frame_index(ii::ParseInteger(*n, "FrameNumber"));
    if (auto t = f.Timestamp()) v.set_timestamp_s(*t);
    auto pose = [&](const char* name) -> std::optional<Eigen::Isometry3d> {
      if (!f.TransformValid(name)) return std::nullopt;
      const Eigen::Matrix4d m = *f.Transform(name);
      if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
        throw std::invalid_argument(std::string(name) + ": last row is not 0 0 0 1");
      }
      Eigen::Isometry3d iso = Eigen::Isometry3d::Identity();
      iso.linear() = m.topLeftCorner<3, 3>();
      iso.translation() = m.topRightCorner<3, 1>();
      return iso;
    };
    if (auto p = pose("ImageToProbeTransform")) v.set_image_to_probe(*p);
    if (auto p = pose("ProbeToReferenceTransform")) v.set_probe_to_reference(*p);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(where + e.what());
  }
  return v;
}

std::vector<Volume> SequenceToVolumes(const PlusSequence& s) {
  std::vector<Volume> out;
  out.reserve(s.frames.size());
  for (std::size_t i = 0; i < s.frames.size(); ++i) out.push_back(SequenceFrameToVolume(s, i));
  return out;
}

PlusSequence SequenceFor(const Volume& first) {
  PlusSequence s;
  const auto& g = first.geometry();
  s.volume_frames = g.dims.z() != 1;
  s.frame_dims = {g.dims.x(), g.dims.y(), g.dims.z()};
  s.spacing_mm = g.spacing_mm;
  s.origin_mm = g.origin_mm;
  s.direction = g.direction;
  s.element_type = "MET_UCHAR";
  s.element_size = 1;
  s.header_fields = {{"UltrasoundImageOrientation", "MFA"}};
  return s;
}

SequenceFrame VolumeFrameFields(const Volume& vol) {
  auto matrix_text = [](const Eigen::Isometry3d& t) {
    std::vector<double> v;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) v.push_back(t.matrix()(r, c));
    return JoinNumbers(v);
  };
  SequenceFrame f;
  f.fields["FrameNumber"] = std::to_string(vol.frame_index());
  f.fields["Timestamp"] = ii::FormatNumber(vol.timestamp_s());
  f.fields["ImageStatus"] = "OK";
  f.fields["ImageToProbeTransform"] = matrix_text(vol.image_to_probe());
  // INVALID when the volume's scanning geometry is unknown (Volume::has_image_to_probe).
  f.fields["ImageToProbeTransformStatus"] = vol.has_image_to_probe() ? "OK" : "INVALID";
  f.fields["ProbeToReferenceTransform"] = matrix_text(vol.probe_to_reference());
  f.fields["ProbeToReferenceTransformStatus"] = "OK";
  return f;
}

PlusSequence VolumesToSequence(std::span<const Volume> volumes) {
  if (volumes.empty()) throw std::invalid_argument("VolumesToSequence: no volumes");
  PlusSequence s = SequenceFor(volumes.front());
  bool all_flat = true;
  for (std::size_t i = 0; i < volumes.size(); ++i) {
    if (!(volumes[i].geometry() == volumes.front().geometry())) {
      throw std::invalid_argument("VolumesToSequence: volume " + std::to_string(i) +
                                  " has a geometry different from volume 0's");
    }
    all_flat = all_flat && volumes[i].geometry().dims.z() == 1;
  }
  s.volume_frames = !all_flat;
  s.pixels.reserve(volumes.size() * volumes.front().voxel_count());
  for (const auto& vol : volumes) {
    s.frames.push_back(VolumeFrameFields(vol));
    s.pixels.insert(s.pixels.end(), vol.voxels().begin(), vol.voxels().end());
  }
  return s;
}

}  // namespace echoservo::imaging

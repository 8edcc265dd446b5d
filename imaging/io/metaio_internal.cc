#include "imaging/io/metaio_internal.h"

#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <system_error>

namespace echoservo::imaging::io_internal {
namespace fs = std::filesystem;

namespace {

[[noreturn]] void Fail(const fs::path& path, const std::string& what) {
  throw std::invalid_argument(path.string() + ": " + what);
}

bool IEquals(const std::string& a, const std::string& b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

// Reads lines from a binary stream in blocks, never holding more than the header cap.
class LineReader {
 public:
  explicit LineReader(std::ifstream& in) : in_(in) {}
  // Next line without its '\n' (and a trailing '\r'); false at end of file.
  bool Next(std::string& line) {
    line.clear();
    while (true) {
      if (pos_ == buf_.size()) {
        buf_.resize(1 << 16);
        in_.read(buf_.data(), static_cast<std::streamsize>(buf_.size()));
        buf_.resize(static_cast<std::size_t>(in_.gcount()));
        pos_ = 0;
        if (buf_.empty()) {
          if (line.empty()) return false;
          consumed_ += 0;
          break;
        }
      }
      const auto nl = std::find(buf_.begin() + static_cast<std::ptrdiff_t>(pos_), buf_.end(), '\n');
      const auto n = static_cast<std::size_t>(nl - buf_.begin()) - pos_;
      line.append(buf_.data() + pos_, n);
      consumed_ += n;
      pos_ += n;
      if (consumed_ > kMaxHeaderBytes) return false;
      if (nl != buf_.end()) {
        ++pos_;
        ++consumed_;
        break;
      }
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }
  std::uint64_t consumed() const { return consumed_; }

 private:
  std::ifstream& in_;
  std::vector<char> buf_;
  std::size_t pos_ = 0;
  std::uint64_t consumed_ = 0;
};

std::uint64_t FileSize(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) Fail(path, "no such file");
  if (!fs::is_regular_file(path, ec)) Fail(path, "not a regular file");
  const auto size = fs::file_size(path, ec);
  if (ec) Fail(path, "cannot get the file size: " + ec.message());
  return size;
}

// The size of a header's detached data file; a missing one is an error naming the header,
// the key and value that point to it, and where it was looked for.
std::uint64_t DataFileSize(const fs::path& header, const std::string& key, const std::string& value,
                           const fs::path& data_path) {
  std::error_code ec;
  if (!fs::exists(data_path, ec)) {
    fs::path dir = data_path.parent_path();
    if (dir.empty()) dir = ".";
    const fs::path abs = fs::absolute(dir, ec);
    Fail(header, key + " '" + value + "' not found (looked in " +
                     (ec ? dir : abs).lexically_normal().string() + ")");
  }
  if (!fs::is_regular_file(data_path, ec)) {
    Fail(header, key + " '" + value + "' (" + data_path.string() + ") is not a regular file");
  }
  return FileSize(data_path);
}

}  // namespace

std::string Trim(const std::string& s) {
  const auto* ws = " \t\r\n\f\v";
  const auto b = s.find_first_not_of(ws);
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(ws);
  return s.substr(b, e - b + 1);
}

std::string FormatNumber(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  // Prefer the shortest representation that reads back exactly (keeps files readable).
  for (int prec = 6; prec < 17; ++prec) {
    char shorter[64];
    std::snprintf(shorter, sizeof shorter, "%.*g", prec, v);
    double back = 0.0;
    std::from_chars(shorter, shorter + std::char_traits<char>::length(shorter), back);
    if (back == v) return shorter;
  }
  return buf;
}

std::vector<double> ParseNumbers(const std::string& text, const std::string& where) {
  std::vector<double> out;
  const char* p = text.data();
  const char* end = p + text.size();
  while (p < end) {
    while (p < end && std::isspace(static_cast<unsigned char>(*p))) ++p;
    if (p == end) break;
    const char* tok_end = p;
    while (tok_end < end && !std::isspace(static_cast<unsigned char>(*tok_end))) ++tok_end;
    double v = 0.0;
    const char* q = p;
    if (q < tok_end && *q == '+') ++q;
    const auto r = std::from_chars(q, tok_end, v);
    if (r.ec != std::errc() || r.ptr != tok_end || !std::isfinite(v)) {
      throw std::invalid_argument(where + ": '" + std::string(p, tok_end) +
                                  "' is not a finite number");
    }
    out.push_back(v);
    p = tok_end;
  }
  return out;
}

std::int64_t ParseInteger(const std::string& text, const std::string& where) {
  const std::string t = Trim(text);
  std::int64_t v = 0;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  if (t.empty() || r.ec != std::errc() || r.ptr != t.data() + t.size()) {
    throw std::invalid_argument(where + ": '" + t + "' is not an integer");
  }
  return v;
}

std::optional<int> MetaElementSize(const std::string& t) {
  if (t == "MET_UCHAR" || t == "MET_CHAR") return 1;
  if (t == "MET_USHORT" || t == "MET_SHORT") return 2;
  if (t == "MET_UINT" || t == "MET_INT" || t == "MET_FLOAT") return 4;
  if (t == "MET_ULONG_LONG" || t == "MET_LONG_LONG" || t == "MET_DOUBLE") return 8;
  if (t == "MET_ULONG" || t == "MET_LONG") return 4;  // MetaIO: 32-bit
  if (t == "MET_OTHER") return 0;
  return std::nullopt;
}

std::optional<std::string> TextHeader::Find(const std::string& key) const {
  for (auto it = entries.rbegin(); it != entries.rend(); ++it) {
    if (syntax == HeaderSyntax::kNrrd && !it->nrrd_keyvalue ? IEquals(it->key, key)
                                                            : it->key == key) {
      return it->value;
    }
  }
  return std::nullopt;
}

std::string TextHeader::Require(const std::string& key) const {
  auto v = Find(key);
  if (!v) throw std::invalid_argument(Where() + "header has no '" + key + "' field");
  return *v;
}

TextHeader ReadTextHeader(const fs::path& path) {
  const std::uint64_t size = FileSize(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail(path, "cannot open for reading");
  TextHeader h;
  h.path = path;
  LineReader reader(in);
  std::string line;
  if (!reader.Next(line)) Fail(path, "empty file (no header)");
  std::size_t line_no = 1;
  std::string data_key, data_value;  // the detached data file's key and value, if any
  if (line.rfind("NRRD", 0) == 0) {
    h.syntax = HeaderSyntax::kNrrd;
    bool ended = false;
    while (reader.Next(line)) {
      ++line_no;
      if (line.empty()) {
        ended = true;
        break;
      }
      if (line[0] == '#') continue;
      TextHeader::Entry e;
      if (auto kv = line.find(":="); kv != std::string::npos) {
        e = {line.substr(0, kv), Trim(line.substr(kv + 2)), true};
      } else if (auto f = line.find(": "); f != std::string::npos) {
        e = {Trim(line.substr(0, f)), Trim(line.substr(f + 2)), false};
      } else {
        Fail(path, "NRRD header line " + std::to_string(line_no) +
                       " is neither 'field: value' nor 'key:=value'");
      }
      h.entries.push_back(std::move(e));
    }
    if (!ended)
      Fail(path, "NRRD header does not end with a blank line (truncated or not a NRRD file)");
    h.data_path = path;
    h.data_offset = reader.consumed();
    if (auto df = h.Find("data file"); df || (df = h.Find("datafile"))) {
      h.data_path = path.parent_path() / *df;
      h.data_offset = 0;
      data_key = "data file";
      data_value = *df;
    }
  } else {
    h.syntax = HeaderSyntax::kMetaImage;
    bool ended = false;
    do {
      if (Trim(line).empty()) continue;
      const auto eq = line.find('=');
      if (eq == std::string::npos) {
        std::string next;
        if (!reader.Next(next)) {
          Fail(path,
               "MetaImage header ends mid-line without an ElementDataFile line (truncated file?)");
        }
        Fail(path, "MetaImage header line " + std::to_string(line_no) +
                       " is not 'Key = Value' (not a MetaImage file, or no ElementDataFile line)");
      }
      h.entries.push_back({Trim(line.substr(0, eq)), Trim(line.substr(eq + 1)), false});
      if (h.entries.back().key == "ElementDataFile") {
        ended = true;
        break;
      }
    } while (++line_no, reader.Next(line));
    if (!ended) {
      Fail(path, reader.consumed() > kMaxHeaderBytes
                     ? "header longer than 512 MiB (not a MetaImage file?)"
                     : "MetaImage header has no ElementDataFile line (truncated file?)");
    }
    const std::string df = h.entries.back().value;
    if (df == "LOCAL") {
      h.data_path = path;
      h.data_offset = reader.consumed();
    } else if (df == "LIST" || df.find('%') != std::string::npos ||
               df.find(' ') != std::string::npos) {
      Fail(path, "ElementDataFile = " + df + ": file lists/patterns are not supported");
    } else {
      h.data_path = path.parent_path() / df;
      h.data_offset = 0;
      data_key = "ElementDataFile";
      data_value = df;
    }
  }
  const std::uint64_t data_size =
      h.data_path == path ? size : DataFileSize(path, data_key, data_value, h.data_path);
  if (h.data_offset > data_size) Fail(path, "header runs past the end of the file");
  h.data_available = data_size - h.data_offset;
  return h;
}

namespace {

std::uint64_t CheckedProduct(const std::vector<std::int64_t>& dims, int element_size,
                             std::uint64_t cap, const std::string& where,
                             const std::string& dims_text) {
  std::uint64_t n = 1;
  bool zero = false;
  for (auto d : dims) {
    if (d < 0) throw std::invalid_argument(where + "negative size in '" + dims_text + "'");
    if (d == 0) zero = true;
  }
  if (zero) return 0;
  for (auto d : dims) {
    if (n > cap / static_cast<std::uint64_t>(d)) {
      throw std::invalid_argument(where + "sizes '" + dims_text + "' exceed the " +
                                  ByteCapText(cap) + " cap");
    }
    n *= static_cast<std::uint64_t>(d);
  }
  const auto es = static_cast<std::uint64_t>(std::max(element_size, 1));
  if (n > cap / es) {
    throw std::invalid_argument(where + "sizes '" + dims_text + "' × " + std::to_string(es) +
                                " bytes exceed the " + ByteCapText(cap) + " cap");
  }
  return n * static_cast<std::uint64_t>(element_size);
}

std::optional<std::string> NrrdTypeToMeta(std::string t) {
  for (auto& c : t) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (t == "uchar" || t == "unsigned char" || t == "uint8" || t == "uint8_t") return "MET_UCHAR";
  if (t == "signed char" || t == "int8" || t == "int8_t") return "MET_CHAR";
  if (t == "ushort" || t == "unsigned short" || t == "unsigned short int" || t == "uint16" ||
      t == "uint16_t")
    return "MET_USHORT";
  if (t == "short" || t == "short int" || t == "signed short" || t == "signed short int" ||
      t == "int16" || t == "int16_t")
    return "MET_SHORT";
  if (t == "uint" || t == "unsigned int" || t == "uint32" || t == "uint32_t") return "MET_UINT";
  if (t == "int" || t == "signed int" || t == "int32" || t == "int32_t") return "MET_INT";
  if (t == "float") return "MET_FLOAT";
  if (t == "double") return "MET_DOUBLE";
  return std::nullopt;
}

// "(1,0,0) (0,1,0) none" → vectors (none → empty).
std::vector<std::vector<double>> ParseSpaceDirections(const std::string& text,
                                                      const std::string& where) {
  std::vector<std::vector<double>> out;
  std::size_t p = 0;
  while (p < text.size()) {
    while (p < text.size() && std::isspace(static_cast<unsigned char>(text[p]))) ++p;
    if (p >= text.size()) break;
    if (text.compare(p, 4, "none") == 0) {
      out.emplace_back();
      p += 4;
    } else if (text[p] == '(') {
      const auto close = text.find(')', p);
      if (close == std::string::npos) throw std::invalid_argument(where + ": unbalanced '('");
      std::string inner = text.substr(p + 1, close - p - 1);
      std::replace(inner.begin(), inner.end(), ',', ' ');
      out.push_back(ParseNumbers(inner, where));
      p = close + 1;
    } else {
      throw std::invalid_argument(where + ": expected '(...)' or 'none' in '" + text + "'");
    }
  }
  return out;
}

}  // namespace

std::string ByteCapText(std::uint64_t bytes) {
  if (bytes % (1ULL << 30) == 0) return std::to_string(bytes >> 30) + " GiB";
  if (bytes % (1ULL << 20) == 0) return std::to_string(bytes >> 20) + " MiB";
  return std::to_string(bytes) + " bytes";
}

PixelLayout CheckPixelLayout(const TextHeader& h, std::uint64_t max_pixel_bytes) {
  PixelLayout L;
  const std::string where = h.Where();
  std::string dims_text;
  if (h.syntax == HeaderSyntax::kMetaImage) {
    if (auto b = h.Find("BinaryData"); b && *b != "True") {
      throw std::invalid_argument(where + "BinaryData = " + *b +
                                  ": ASCII pixel data is not supported");
    }
    const auto ndims = ParseInteger(h.Require("NDims"), where + "NDims");
    if (ndims < 1 || ndims > 4) {
      throw std::invalid_argument(where + "NDims = " + std::to_string(ndims) +
                                  " (1 to 4 supported)");
    }
    dims_text = "DimSize = " + h.Require("DimSize");
    for (double d : ParseNumbers(h.Require("DimSize"), where + "DimSize")) {
      if (d != std::floor(d) || d < 0 || d > 1e12) {
        throw std::invalid_argument(where + dims_text + ": sizes must be non-negative integers");
      }
      L.dims.push_back(static_cast<std::int64_t>(d));
    }
    if (static_cast<std::int64_t>(L.dims.size()) != ndims) {
      throw std::invalid_argument(where + dims_text + " has " + std::to_string(L.dims.size()) +
                                  " numbers but NDims = " + std::to_string(ndims));
    }
    L.element_type = h.Find("ElementType").value_or("MET_OTHER");
    const auto es = MetaElementSize(L.element_type);
    if (!es) throw std::invalid_argument(where + "unknown ElementType " + L.element_type);
    L.element_size = *es;
    if (auto ch = h.Find("ElementNumberOfChannels"); ch && Trim(*ch) != "1") {
      throw std::invalid_argument(where + "ElementNumberOfChannels = " + *ch +
                                  ": only single-channel images are supported");
    }
    for (const char* msb : {"BinaryDataByteOrderMSB", "ElementByteOrderMSB"}) {
      if (auto v = h.Find(msb); v && *v == "True" && L.element_size > 1) {
        throw std::invalid_argument(where + msb + " = True: big-endian data is not supported");
      }
    }
    const std::string c = h.Find("CompressedData").value_or("False");
    if (c != "True" && c != "False") {
      throw std::invalid_argument(where + "CompressedData = " + c + " (expected True or False)");
    }
    L.compressed = c == "True";
    if (L.compressed) {
      if (auto cs = h.Find("CompressedDataSize")) {
        const auto n = ParseInteger(*cs, where + "CompressedDataSize");
        if (n <= 0)
          throw std::invalid_argument(where + "CompressedDataSize = " + *cs + " must be > 0");
        L.compressed_size = static_cast<std::uint64_t>(n);
        if (L.compressed_size > h.data_available) {
          throw std::invalid_argument(
              where + "CompressedDataSize = " + std::to_string(L.compressed_size) + " but only " +
              std::to_string(h.data_available) + " bytes follow the header (truncated file?)");
        }
      } else {
        L.compressed_size = h.data_available;
      }
    }
  } else {
    const auto dim = ParseInteger(h.Require("dimension"), where + "dimension");
    if (dim < 1 || dim > 4)
      throw std::invalid_argument(where + "dimension: " + std::to_string(dim) +
                                  " (1 to 4 supported)");
    dims_text = "sizes: " + h.Require("sizes");
    for (double d : ParseNumbers(h.Require("sizes"), where + "sizes")) {
      if (d != std::floor(d) || d < 0 || d > 1e12) {
        throw std::invalid_argument(where + dims_text + ": sizes must be non-negative integers");
      }
      L.dims.push_back(static_cast<std::int64_t>(d));
    }
    if (static_cast<std::int64_t>(L.dims.size()) != dim) {
      throw std::invalid_argument(where + dims_text +
                                  " does not have dimension = " + std::to_string(dim) + " numbers");
    }
    const std::string type = h.Require("type");
    const auto meta = NrrdTypeToMeta(type);
    if (!meta) throw std::invalid_argument(where + "unsupported NRRD type: " + type);
    L.element_type = *meta;
    L.element_size = *MetaElementSize(L.element_type);
    const std::string enc = h.Require("encoding");
    if (enc == "gz" || enc == "gzip") {
      L.compressed = true;
      L.compressed_size = h.data_available;
    } else if (enc != "raw") {
      throw std::invalid_argument(where + "encoding: " + enc + " (only raw and gz are supported)");
    }
    if (auto e = h.Find("endian"); e && *e == "big" && L.element_size > 1) {
      throw std::invalid_argument(where + "endian: big is not supported");
    }
    for (const char* skip : {"line skip", "lineskip", "byte skip", "byteskip"}) {
      if (auto v = h.Find(skip); v && Trim(*v) != "0") {
        throw std::invalid_argument(where + skip + ": " + *v + " is not supported");
      }
    }
    if (auto sd = h.Find("space directions")) {
      L.nrrd_space_directions = ParseSpaceDirections(*sd, where + "space directions");
      if (L.nrrd_space_directions.size() != L.dims.size()) {
        throw std::invalid_argument(where + "space directions has " +
                                    std::to_string(L.nrrd_space_directions.size()) +
                                    " entries for " + std::to_string(L.dims.size()) + " axes");
      }
    }
    if (auto so = h.Find("space origin")) {
      std::string t = *so;
      std::replace(t.begin(), t.end(), '(', ' ');
      std::replace(t.begin(), t.end(), ')', ' ');
      std::replace(t.begin(), t.end(), ',', ' ');
      L.nrrd_space_origin = ParseNumbers(t, where + "space origin");
    }
  }
  L.pixel_bytes = CheckedProduct(L.dims, L.element_size, max_pixel_bytes, where, dims_text);
  bool any_pixels = true;
  for (auto d : L.dims) any_pixels = any_pixels && d > 0;
  if (any_pixels && L.element_size == 0) {
    throw std::invalid_argument(where + "ElementType " + L.element_type + " with non-empty " +
                                dims_text);
  }
  if (!L.compressed && L.pixel_bytes > h.data_available) {
    throw std::invalid_argument(where + dims_text + " (" + L.element_type + ") needs " +
                                std::to_string(L.pixel_bytes) + " bytes of pixel data but only " +
                                std::to_string(h.data_available) +
                                " follow the header (truncated file or wrong DimSize)");
  }
  if (L.compressed && L.pixel_bytes > L.compressed_size * kMaxDeflateRatio + 1024) {
    throw std::invalid_argument(where + dims_text + " needs " + std::to_string(L.pixel_bytes) +
                                " bytes, more than a compressed stream of " +
                                std::to_string(L.compressed_size) + " bytes can hold");
  }
  return L;
}

std::vector<std::uint8_t> ReadPixels(const TextHeader& h, const PixelLayout& L) {
  std::ifstream in(h.data_path, std::ios::binary);
  if (!in) Fail(h.data_path, "cannot open for reading");
  in.seekg(static_cast<std::streamoff>(h.data_offset));
  const std::uint64_t to_read = L.compressed ? L.compressed_size : L.pixel_bytes;
  std::vector<std::uint8_t> raw(static_cast<std::size_t>(to_read));  // ≤ bytes in the file
  in.read(reinterpret_cast<char*>(raw.data()), static_cast<std::streamsize>(raw.size()));
  if (static_cast<std::uint64_t>(in.gcount()) != to_read) {
    Fail(h.data_path, "could not read " + std::to_string(to_read) + " bytes of pixel data");
  }
  if (!L.compressed) return raw;
  return Inflate(raw, L.pixel_bytes, h.Where() + "compressed pixel data");
}

std::vector<std::uint8_t> Inflate(std::span<const std::uint8_t> in, std::uint64_t expected,
                                  const std::string& where) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(expected));
  z_stream s{};
  if (inflateInit2(&s, 15 + 32) != Z_OK) throw std::runtime_error(where + ": zlib init failed");
  constexpr std::uint64_t kChunk = 1ULL << 30;
  std::uint64_t in_pos = 0;
  std::uint64_t out_pos = 0;
  int rc = Z_OK;
  while (true) {
    if (s.avail_in == 0 && in_pos < in.size()) {
      const auto n = std::min<std::uint64_t>(kChunk, in.size() - in_pos);
      s.next_in = const_cast<Bytef*>(in.data() + in_pos);
      s.avail_in = static_cast<uInt>(n);
      in_pos += n;
    }
    if (s.avail_out == 0 && out_pos < out.size()) {
      const auto n = std::min<std::uint64_t>(kChunk, out.size() - out_pos);
      s.next_out = out.data() + out_pos;
      s.avail_out = static_cast<uInt>(n);
      out_pos += n;
    }
    std::uint8_t probe = 0;
    const bool output_full = s.avail_out == 0 && out_pos == out.size();
    if (output_full) {  // everything expected is in; the stream must end now
      s.next_out = &probe;
      s.avail_out = 1;
    }
    rc = inflate(&s, Z_NO_FLUSH);
    if (output_full && s.avail_out == 0) {
      inflateEnd(&s);
      throw std::invalid_argument(where + ": decompresses to more than the " +
                                  std::to_string(expected) + " bytes the sizes declare");
    }
    if (rc == Z_STREAM_END) break;
    if (rc == Z_DATA_ERROR || rc == Z_NEED_DICT || rc == Z_MEM_ERROR) {
      const std::string msg = s.msg != nullptr ? s.msg : "error " + std::to_string(rc);
      inflateEnd(&s);
      throw std::invalid_argument(where + ": corrupt compressed data (zlib: " + msg + ")");
    }
    if (rc == Z_BUF_ERROR && s.avail_in == 0 && in_pos == in.size()) {
      inflateEnd(&s);
      throw std::invalid_argument(where + ": truncated compressed stream (ends after " +
                                  std::to_string(s.total_out) + " of " + std::to_string(expected) +
                                  " bytes; file truncated or CompressedDataSize too small)");
    }
    if (output_full && rc == Z_OK && s.avail_in == 0 && in_pos == in.size()) {
      inflateEnd(&s);
      throw std::invalid_argument(where + ": truncated compressed stream (no end marker)");
    }
  }
  const std::uint64_t total = s.total_out;
  inflateEnd(&s);
  if (total != expected) {
    throw std::invalid_argument(where + ": decompressed to " + std::to_string(total) +
                                " bytes, the sizes declare " + std::to_string(expected));
  }
  return out;
}

std::vector<std::uint8_t> Deflate(std::span<const std::uint8_t> in, bool gzip) {
  z_stream s{};
  if (deflateInit2(&s, Z_DEFAULT_COMPRESSION, Z_DEFLATED, gzip ? 15 + 16 : 15, 8,
                   Z_DEFAULT_STRATEGY) != Z_OK) {
    throw std::runtime_error("zlib deflateInit2 failed");
  }
  std::vector<std::uint8_t> out;
  constexpr std::size_t kChunk = 1 << 20;
  std::size_t in_pos = 0;
  int rc = Z_OK;
  do {
    if (s.avail_in == 0 && in_pos < in.size()) {
      const auto n = std::min<std::size_t>(std::size_t{1} << 30, in.size() - in_pos);
      s.next_in = const_cast<Bytef*>(in.data() + in_pos);
      s.avail_in = static_cast<uInt>(n);
      in_pos += n;
    }
    const std::size_t old = out.size();
    out.resize(old + kChunk);
    s.next_out = out.data() + old;
    s.avail_out = static_cast<uInt>(kChunk);
    rc = deflate(&s, in_pos == in.size() ? Z_FINISH : Z_NO_FLUSH);
    out.resize(old + kChunk - s.avail_out);
  } while (rc != Z_STREAM_END);
  deflateEnd(&s);
  return out;
}

}  // namespace echoservo::imaging::io_internal

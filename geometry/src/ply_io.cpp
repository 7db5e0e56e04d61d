// PLY (Stanford polygon format), hand-written: assimp 5.2 reads well-formed PLY correctly
// but accepts malformed files silently (out-of-range indices, faces without their count),
// throws bad_alloc on absurd element counts and names no line or byte (docs/FORMATS.md).
//
// Reads ascii, binary_little_endian and binary_big_endian. The "vertex" element needs
// scalar properties x, y, z (any type); the "face" element needs a list property
// "vertex_indices" (or "vertex_index"); polygons are fan-triangulated; every other
// property and element is skipped. Counts from the header are checked against the bytes
// that follow before anything is allocated.
#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "mesh_formats.hpp"
#include "evar/base/atomic_file.hpp"

namespace evar::geometry::detail {

namespace {

enum class Scalar { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

struct ScalarName {
  std::string_view name;
  Scalar type;
};
constexpr ScalarName kScalarNames[] = {
    {"char", Scalar::Int8},     {"int8", Scalar::Int8},       {"uchar", Scalar::UInt8},
    {"uint8", Scalar::UInt8},   {"short", Scalar::Int16},     {"int16", Scalar::Int16},
    {"ushort", Scalar::UInt16}, {"uint16", Scalar::UInt16},   {"int", Scalar::Int32},
    {"int32", Scalar::Int32},   {"uint", Scalar::UInt32},     {"uint32", Scalar::UInt32},
    {"float", Scalar::Float32}, {"float32", Scalar::Float32}, {"double", Scalar::Float64},
    {"float64", Scalar::Float64},
};

std::optional<Scalar> scalar_from_name(std::string_view name) {
  for (const auto& s : kScalarNames) {
    if (s.name == name) return s.type;
  }
  return std::nullopt;
}

std::size_t size_of(Scalar t) {
  switch (t) {
    case Scalar::Int8:
    case Scalar::UInt8: return 1;
    case Scalar::Int16:
    case Scalar::UInt16: return 2;
    case Scalar::Int32:
    case Scalar::UInt32:
    case Scalar::Float32: return 4;
    case Scalar::Float64: return 8;
  }
  return 0;
}

bool is_integer(Scalar t) { return t != Scalar::Float32 && t != Scalar::Float64; }

struct Property {
  std::string name;
  bool is_list = false;
  Scalar count_type = Scalar::UInt8;  ///< lists only
  Scalar type = Scalar::Float32;      ///< the value type, or the item type of a list
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
  std::size_t header_line = 0;
};

enum class Encoding { Ascii, BinaryLittle, BinaryBig };

struct Header {
  Encoding encoding = Encoding::Ascii;
  std::vector<Element> elements;
  std::size_t body_offset = 0;  ///< first byte after "end_header\n"
  std::size_t body_line = 0;    ///< line number of the first body line (ASCII)
};

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t p = 0;
  while (p < line.size()) {
    while (p < line.size() && is_space(line[p])) ++p;
    const std::size_t start = p;
    while (p < line.size() && !is_space(line[p])) ++p;
    if (p > start) words.push_back(line.substr(start, p - start));
  }
  return words;
}

Header parse_header(const std::filesystem::path& path, std::string_view bytes) {
  Header h;
  std::size_t pos = 0;
  std::size_t line_no = 0;
  auto next_line = [&]() -> std::optional<std::string_view> {
    if (pos >= bytes.size()) return std::nullopt;
    std::size_t end = bytes.find('\n', pos);
    if (end == std::string_view::npos) end = bytes.size();
    std::string_view line = bytes.substr(pos, end - pos);
    pos = end < bytes.size() ? end + 1 : end;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    ++line_no;
    return line;
  };
  auto bad = [&](const std::string& what) { fail(path, "line " + std::to_string(line_no) + ": " + what); };

  const auto first = next_line();
  if (!first || *first != "ply") fail(path, "not a PLY file: the first line is not 'ply'");

  bool have_format = false;
  for (;;) {
    const auto line = next_line();
    if (!line) fail(path, "PLY header has no 'end_header' line (truncated?)");
    const auto words = split_words(*line);
    if (words.empty()) continue;
    const std::string_view key = words[0];
    if (key == "comment" || key == "obj_info") continue;
    if (key == "end_header") {
      if (!have_format) fail(path, "PLY header has no 'format' line");
      h.body_offset = pos;
      h.body_line = line_no + 1;
      return h;
    }
    if (key == "format") {
      if (have_format) bad("second 'format' line");
      if (words.size() != 3) bad("expected 'format <ascii|binary_little_endian|binary_big_endian> 1.0'");
      if (words[1] == "ascii") h.encoding = Encoding::Ascii;
      else if (words[1] == "binary_little_endian") h.encoding = Encoding::BinaryLittle;
      else if (words[1] == "binary_big_endian") h.encoding = Encoding::BinaryBig;
      else bad("unknown PLY format " + quoted(words[1]));
      have_format = true;
    } else if (key == "element") {
      if (words.size() != 3) bad("expected 'element <name> <count>'");
      Element e;
      e.name = std::string(words[1]);
      e.header_line = line_no;
      if (parse_number(words[2], e.count) != NumberParse::Ok) {
        bad("element count " + quoted(words[2]) + " is not a non-negative integer");
      }
      for (const auto& other : h.elements) {
        if (other.name == e.name) bad("element '" + e.name + "' is declared twice");
      }
      h.elements.push_back(std::move(e));
    } else if (key == "property") {
      if (h.elements.empty()) bad("'property' before any 'element'");
      Property p;
      if (words.size() >= 2 && words[1] == "list") {
        if (words.size() != 5) bad("expected 'property list <count type> <item type> <name>'");
        const auto count_type = scalar_from_name(words[2]);
        const auto item_type = scalar_from_name(words[3]);
        if (!count_type) bad("unknown property type " + quoted(words[2]));
        if (!item_type) bad("unknown property type " + quoted(words[3]));
        if (!is_integer(*count_type)) bad("list count type must be an integer type");
        p.is_list = true;
        p.count_type = *count_type;
        p.type = *item_type;
        p.name = std::string(words[4]);
      } else {
        if (words.size() != 3) bad("expected 'property <type> <name>'");
        const auto type = scalar_from_name(words[1]);
        if (!type) bad("unknown property type " + quoted(words[1]));
        p.type = *type;
        p.name = std::string(words[2]);
      }
      h.elements.back().properties.push_back(std::move(p));
    } else {
      bad("unexpected PLY header line starting with " + quoted(key));
    }
  }
}

// ---- body readers: the same element loop runs over binary bytes or ASCII tokens ----

// Where we are, for messages: which element and which item of it.
struct Context {
  const std::filesystem::path* path = nullptr;
  const Element* element = nullptr;
  std::uint64_t item = 0;
};

class BinaryReader {
 public:
  BinaryReader(const Context& ctx, std::string_view bytes, std::size_t offset, bool swap)
      : ctx_(ctx), bytes_(bytes), pos_(offset), swap_(swap) {}

  /// A cheap position for messages; where(mark) formats it only when needed.
  std::size_t mark() const { return pos_; }
  static std::string where(std::size_t mark) { return "byte " + std::to_string(mark); }
  std::string where() const { return where(pos_); }
  std::size_t remaining() const { return bytes_.size() - pos_; }

  double read_real(Scalar t) {
    switch (t) {
      case Scalar::Int8: return static_cast<double>(load<std::int8_t>());
      case Scalar::UInt8: return static_cast<double>(load<std::uint8_t>());
      case Scalar::Int16: return static_cast<double>(load<std::int16_t>());
      case Scalar::UInt16: return static_cast<double>(load<std::uint16_t>());
      case Scalar::Int32: return static_cast<double>(load<std::int32_t>());
      case Scalar::UInt32: return static_cast<double>(load<std::uint32_t>());
      case Scalar::Float32: return static_cast<double>(load<float>());
      case Scalar::Float64: return load<double>();
    }
    return 0.0;
  }

  std::int64_t read_int(Scalar t) {
    switch (t) {
      case Scalar::Int8: return load<std::int8_t>();
      case Scalar::UInt8: return load<std::uint8_t>();
      case Scalar::Int16: return load<std::int16_t>();
      case Scalar::UInt16: return load<std::uint16_t>();
      case Scalar::Int32: return load<std::int32_t>();
      case Scalar::UInt32: return load<std::uint32_t>();
      case Scalar::Float32:
      case Scalar::Float64: break;  // the header check keeps floats out of integer slots
    }
    fail(*ctx_.path, where() + ": internal error: integer read of a float property");
  }

  void skip(Scalar t, std::uint64_t n = 1) {
    need(n * size_of(t));
    pos_ += static_cast<std::size_t>(n * size_of(t));
  }

  /// Whether a list of n items could fit in the rest of the file (checked before looping).
  bool list_fits(std::uint64_t n, Scalar item_type) const {
    return n <= remaining() / size_of(item_type);
  }

  void finish() const {}  // trailing bytes after the last element are tolerated

 private:
  template <class T>
  T load() {
    need(sizeof(T));
    T value;
    std::memcpy(&value, bytes_.data() + pos_, sizeof(T));  // no unaligned reads
    if (swap_) reverse_bytes(&value, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }

  void need(std::uint64_t n) const {
    if (n > remaining()) truncated("file ends early (truncated?)");
  }

  [[noreturn]] void truncated(const std::string& what) const {
    fail(*ctx_.path, where() + ": element '" + ctx_.element->name + "' item " +
                         std::to_string(ctx_.item) + ": " + what);
  }

  const Context& ctx_;
  std::string_view bytes_;
  std::size_t pos_;
  bool swap_;
};

class AsciiReader {
 public:
  AsciiReader(const Context& ctx, std::string_view bytes, std::size_t offset, std::size_t line)
      : ctx_(ctx), bytes_(bytes), pos_(offset), line_(line), token_line_(line) {}

  /// The line of the next token (skipping to it is harmless).
  std::size_t mark() {
    skip_space();
    return line_;
  }
  static std::string where(std::size_t mark) { return "line " + std::to_string(mark); }
  std::string where() const { return where(token_line_); }
  std::size_t remaining() const { return bytes_.size() - pos_; }

  double read_real(Scalar t) {
    if (is_integer(t)) return static_cast<double>(read_int(t));
    const std::string_view tok = token();
    double value = 0.0;
    const NumberParse r = parse_number(tok, value);
    if (r == NumberParse::OutOfRange) bad_value(quoted(tok) + " is out of range");
    if (r != NumberParse::Ok) bad_value(quoted(tok) + " is not a number");
    return value;
  }

  std::int64_t read_int(Scalar t) {
    const std::string_view tok = token();
    std::int64_t value = 0;
    if (parse_number(tok, value) != NumberParse::Ok) bad_value(quoted(tok) + " is not an integer");
    std::int64_t lo = 0, hi = 0;
    switch (t) {
      case Scalar::Int8: lo = INT8_MIN, hi = INT8_MAX; break;
      case Scalar::UInt8: lo = 0, hi = UINT8_MAX; break;
      case Scalar::Int16: lo = INT16_MIN, hi = INT16_MAX; break;
      case Scalar::UInt16: lo = 0, hi = UINT16_MAX; break;
      case Scalar::Int32: lo = INT32_MIN, hi = INT32_MAX; break;
      case Scalar::UInt32: lo = 0, hi = UINT32_MAX; break;
      case Scalar::Float32:
      case Scalar::Float64: return value;
    }
    if (value < lo || value > hi) bad_value(quoted(tok) + " is out of range for its type");
    return value;
  }

  void skip(Scalar t, std::uint64_t n = 1) {
    for (std::uint64_t i = 0; i < n; ++i) read_real(t);  // still checked: catches misalignment
  }

  bool list_fits(std::uint64_t n, Scalar) const {
    return n <= remaining();  // every value takes at least one byte
  }

  void finish() {
    const std::string_view tok = next();
    if (!tok.empty()) {
      fail(*ctx_.path, where() + ": unexpected data " + quoted(tok) +
                           " after the last element (wrong element count in the header?)");
    }
  }

 private:
  void skip_space() {
    while (pos_ < bytes_.size() && is_space(bytes_[pos_])) {
      if (bytes_[pos_] == '\n') ++line_;
      ++pos_;
    }
  }

  std::string_view next() {
    skip_space();
    token_line_ = line_;
    const std::size_t start = pos_;
    while (pos_ < bytes_.size() && !is_space(bytes_[pos_])) ++pos_;
    return bytes_.substr(start, pos_ - start);
  }

  std::string_view token() {
    const std::string_view tok = next();
    if (tok.empty()) bad_value("file ends early (truncated?)");
    return tok;
  }

  [[noreturn]] void bad_value(const std::string& what) const {
    fail(*ctx_.path, where() + ": element '" + ctx_.element->name + "' item " +
                         std::to_string(ctx_.item) + ": " + what);
  }

  const Context& ctx_;
  std::string_view bytes_;
  std::size_t pos_;
  std::size_t line_;
  std::size_t token_line_;
};

std::uint64_t read_list_count(auto& reader, const Property& p, const Context& ctx) {
  const std::size_t at = reader.mark();
  const std::int64_t n = reader.read_int(p.count_type);
  if (n < 0) {
    fail(*ctx.path, reader.where(at) + ": element '" + ctx.element->name + "' item " + std::to_string(ctx.item) +
                        ": list '" + p.name + "' has negative length " + std::to_string(n));
  }
  const auto count = static_cast<std::uint64_t>(n);
  if (!reader.list_fits(count, p.type)) {
    fail(*ctx.path, reader.where(at) + ": element '" + ctx.element->name + "' item " +
                        std::to_string(ctx.item) + ": list '" + p.name + "' of " +
                        std::to_string(count) + " items does not fit in the " +
                        std::to_string(reader.remaining()) + " bytes left");
  }
  return count;
}

struct Layout {
  const Element* vertex = nullptr;
  int x = -1, y = -1, z = -1;  // property indices in the vertex element
  const Element* face = nullptr;
  int indices = -1;  // property index of the vertex index list in the face element
};

template <class Reader>
TriangleMesh read_body(const std::filesystem::path& path, const Header& h, const Layout& layout,
                       Reader& reader, Context& ctx) {
  TriangleMesh mesh;
  const auto nv = static_cast<std::int64_t>(layout.vertex->count);
  mesh.V.resize(static_cast<Eigen::Index>(nv), 3);
  std::vector<int> faces;
  if (layout.face) faces.reserve(static_cast<std::size_t>(layout.face->count) * 3);

  for (const Element& e : h.elements) {
    ctx.element = &e;
    const bool is_vertex = &e == layout.vertex;
    const bool is_face = &e == layout.face;
    for (ctx.item = 0; ctx.item < e.count; ++ctx.item) {
      const std::size_t item_at = reader.mark();
      for (std::size_t pi = 0; pi < e.properties.size(); ++pi) {
        const Property& p = e.properties[pi];
        const int ipi = static_cast<int>(pi);
        if (is_face && ipi == layout.indices) {
          const std::size_t at = reader.mark();
          const std::uint64_t n = read_list_count(reader, p, ctx);
          if (n < 3) {
            fail(path, reader.where(at) + ": face " + std::to_string(ctx.item) + " has " + std::to_string(n) +
                           " vertex indices; a polygon needs at least 3");
          }
          int first = 0, previous = 0;
          for (std::uint64_t k = 0; k < n; ++k) {
            const std::size_t index_at = reader.mark();
            const std::int64_t index = reader.read_int(p.type);
            if (index < 0 || index >= nv) {
              fail(path, reader.where(index_at) + ": face " + std::to_string(ctx.item) + " has vertex index " +
                             std::to_string(index) + " but the file has " + std::to_string(nv) +
                             " vertices");
            }
            const int i = static_cast<int>(index);
            if (k == 0) first = i;
            if (k >= 2) faces.insert(faces.end(), {first, previous, i});  // fan
            previous = i;
          }
          if (faces.size() / 3 > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
            fail(path, reader.where(at) + ": too many triangles");
          }
        } else if (p.is_list) {
          reader.skip(p.type, read_list_count(reader, p, ctx));
        } else if (is_vertex && (ipi == layout.x || ipi == layout.y || ipi == layout.z)) {
          const int axis = ipi == layout.x ? 0 : ipi == layout.y ? 1 : 2;
          mesh.V(static_cast<Eigen::Index>(ctx.item), axis) = reader.read_real(p.type);
        } else {
          reader.skip(p.type);
        }
      }
      if (is_vertex && !mesh.V.row(static_cast<Eigen::Index>(ctx.item)).allFinite()) {
        fail(path, reader.where(item_at) + ": vertex " + std::to_string(ctx.item) + " has a non-finite coordinate");
      }
    }
  }
  reader.finish();

  mesh.F.resize(static_cast<Eigen::Index>(faces.size() / 3), 3);
  std::copy(faces.begin(), faces.end(), mesh.F.data());
  return mesh;
}

Layout find_layout(const std::filesystem::path& path, const Header& h) {
  Layout layout;
  for (const Element& e : h.elements) {
    if (e.name == "vertex") layout.vertex = &e;
    if (e.name == "face") layout.face = &e;
  }
  if (!layout.vertex) fail(path, "PLY header has no 'vertex' element");
  const Element& v = *layout.vertex;
  const auto vline = "line " + std::to_string(v.header_line) + ": ";
  if (v.count > static_cast<std::uint64_t>(std::numeric_limits<int>::max())) {
    fail(path, vline + "element 'vertex' declares " + std::to_string(v.count) +
                   " vertices: more than a mesh index can hold");
  }
  for (std::size_t i = 0; i < v.properties.size(); ++i) {
    const Property& p = v.properties[i];
    int* slot = p.name == "x" ? &layout.x : p.name == "y" ? &layout.y : p.name == "z" ? &layout.z : nullptr;
    if (!slot) continue;
    if (p.is_list) fail(path, vline + "vertex property '" + p.name + "' is a list, expected a number");
    *slot = static_cast<int>(i);
  }
  for (const char* axis : {"x", "y", "z"}) {
    const int slot = axis[0] == 'x' ? layout.x : axis[0] == 'y' ? layout.y : layout.z;
    if (slot < 0) fail(path, vline + "element 'vertex' has no property '" + axis + "'");
  }

  if (layout.face) {
    const Element& f = *layout.face;
    const auto fline = "line " + std::to_string(f.header_line) + ": ";
    if (f.count > static_cast<std::uint64_t>(std::numeric_limits<int>::max())) {
      fail(path, fline + "element 'face' declares " + std::to_string(f.count) + " faces: too many");
    }
    for (std::size_t i = 0; i < f.properties.size(); ++i) {
      const Property& p = f.properties[i];
      if (p.name == "vertex_indices" || p.name == "vertex_index") {
        if (!p.is_list) fail(path, fline + "face property '" + p.name + "' is not a list");
        if (!is_integer(p.type)) {
          fail(path, fline + "face property '" + p.name + "' must hold integers");
        }
        layout.indices = static_cast<int>(i);
        break;
      }
    }
    if (layout.indices < 0) {
      fail(path, fline + "element 'face' has no list property 'vertex_indices'");
    }
  }
  return layout;
}

// The header's counts must fit in the bytes that follow, so a lying header cannot make
// us allocate gigabytes ("element vertex 4000000000" in a 200-byte file).
void check_counts_fit(const std::filesystem::path& path, const Header& h, std::size_t body_bytes) {
  std::uint64_t needed = 0;
  for (const Element& e : h.elements) {
    std::uint64_t per_item = 0;  // binary: bytes; ASCII: tokens of at least one byte each
    for (const Property& p : e.properties) {
      if (h.encoding == Encoding::Ascii) per_item += 1;
      else per_item += size_of(p.is_list ? p.count_type : p.type);
    }
    if (per_item == 0) continue;
    const std::uint64_t left = body_bytes - std::min<std::uint64_t>(needed, body_bytes);
    if (e.count > left / per_item) {
      fail(path, "line " + std::to_string(e.header_line) + ": element '" + e.name + "' declares " +
                     std::to_string(e.count) + " items, which need at least " +
                     (e.count > std::numeric_limits<std::uint64_t>::max() / per_item
                          ? std::string("more than 2^64")
                          : std::to_string(e.count * per_item)) +
                     " bytes, but only " + std::to_string(left) +
                     " bytes of data are left in the file");
    }
    needed += e.count * per_item;
  }
}

// ---- writing -----------------------------------------------------------------------

template <class T>
void put_le(std::string& out, T value) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::big) reverse_bytes(b, sizeof(T));
  out.append(b, sizeof(T));
}

template <class T>
void put_text(std::string& out, T value) {
  char buf[32];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, value);  // shortest exact form
  out.append(buf, ec == std::errc{} ? ptr : buf);
}

}  // namespace

LoadedMesh read_ply(const std::filesystem::path& path, std::string_view bytes) {
  const Header header = parse_header(path, bytes);
  const Layout layout = find_layout(path, header);
  check_counts_fit(path, header, bytes.size() - header.body_offset);

  Context ctx;
  ctx.path = &path;
  if (header.encoding == Encoding::Ascii) {
    AsciiReader reader(ctx, bytes, header.body_offset, header.body_line);
    return {read_body(path, header, layout, reader, ctx), MeshFormat::PlyAscii};
  }
  const bool file_big = header.encoding == Encoding::BinaryBig;
  const bool host_big = std::endian::native == std::endian::big;
  BinaryReader reader(ctx, bytes, header.body_offset, file_big != host_big);
  return {read_body(path, header, layout, reader, ctx), MeshFormat::PlyBinary};
}

void write_ply(const std::filesystem::path& path, const TriangleMesh& mesh, bool binary, std::string_view space_tag) {
  check_indices_for_writing(mesh, path);
  const auto nv = mesh.V.rows();
  const auto nf = mesh.F.rows();
  std::string out;
  out.reserve(256 + static_cast<std::size_t>(nv) * (binary ? 24 : 60) +
              static_cast<std::size_t>(nf) * (binary ? 13 : 30));
  out += "ply\n";
  out += binary ? "format binary_little_endian 1.0\n" : "format ascii 1.0\n";
  out += "comment evarnode: millimetres\n";
  out += "comment ";
  out += space_tag;
  out += '\n';
  // double coordinates: a write/read round trip is exact.
  out += "element vertex " + std::to_string(nv) + "\n";
  out += "property double x\nproperty double y\nproperty double z\n";
  out += "element face " + std::to_string(nf) + "\n";
  out += "property list uchar int vertex_indices\n";
  out += "end_header\n";
  for (Eigen::Index v = 0; v < nv; ++v) {
    for (int k = 0; k < 3; ++k) {
      if (binary) {
        put_le(out, mesh.V(v, k));
      } else {
        if (k) out += ' ';
        put_text(out, mesh.V(v, k));
      }
    }
    if (!binary) out += '\n';
  }
  for (Eigen::Index f = 0; f < nf; ++f) {
    if (binary) {
      put_le(out, std::uint8_t{3});
      for (int k = 0; k < 3; ++k) put_le(out, std::int32_t{mesh.F(f, k)});
    } else {
      out += '3';
      for (int k = 0; k < 3; ++k) {
        out += ' ';
        put_text(out, mesh.F(f, k));
      }
      out += '\n';
    }
  }
  base::write_file_atomically(path, out);
}

}  // namespace evar::geometry::detail

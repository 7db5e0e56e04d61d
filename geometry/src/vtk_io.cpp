// VTK legacy polydata (.vtk), 3D Slicer's default model format, as VTK's vtkPolyDataWriter
// writes it: the header (version line, title, ASCII or BINARY, DATASET POLYDATA), then
// POINTS and cell sections. Cells come as a count and indices per cell (versions up to
// 4.2, which Slicer writes) or as OFFSETS and CONNECTIVITY arrays (5.1, VTK 9's default).
// BINARY values are big-endian. POLYGONS are fan-triangulated and TRIANGLE_STRIPS unrolled;
// VERTICES, LINES, FIELD and METADATA blocks are skipped, and reading stops at POINT_DATA
// or CELL_DATA (attributes, not geometry). Vertex order is the file's.
//
// VTK's own reader is not used: VTK is a large dependency for a few hundred lines, and its
// legacy reader reports malformed files as warnings and returns what it has.
#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "mesh_formats.hpp"
#include "evar/base/atomic_file.hpp"

namespace evar::geometry::detail {

namespace {

// A value type of the legacy format, with its size in a BINARY file.
enum class Kind { Signed, Unsigned, Floating };
struct ValueType {
  std::size_t bytes = 0;
  Kind kind = Kind::Signed;
};

std::optional<ValueType> value_type(std::string_view name) {
  struct Entry {
    std::string_view name;
    ValueType type;
  };
  static constexpr Entry kTypes[] = {
      {"char", {1, Kind::Signed}},           {"signed_char", {1, Kind::Signed}},
      {"unsigned_char", {1, Kind::Unsigned}}, {"short", {2, Kind::Signed}},
      {"unsigned_short", {2, Kind::Unsigned}}, {"int", {4, Kind::Signed}},
      {"unsigned_int", {4, Kind::Unsigned}},  {"long", {8, Kind::Signed}},
      {"unsigned_long", {8, Kind::Unsigned}}, {"vtktypeint64", {8, Kind::Signed}},
      {"vtktypeuint64", {8, Kind::Unsigned}}, {"float", {4, Kind::Floating}},
      {"double", {8, Kind::Floating}},       {"vtkidtype", {4, Kind::Signed}},  // as VTK writes it
  };
  for (const Entry& e : kTypes)
    if (iequals(name, e.name)) return e.type;
  return std::nullopt;
}

// Cell c's point indices are ids[offsets[c] .. offsets[c + 1]).
struct Cells {
  std::vector<std::int64_t> offsets{0};
  std::vector<std::int64_t> ids;
  std::size_t count() const { return offsets.size() - 1; }
};

class VtkReader {
 public:
  VtkReader(const std::filesystem::path& path, std::string_view bytes) : path_(path), s_(bytes) {}

  LoadedMesh read() {
    constexpr std::string_view kMagic = "# vtk DataFile Version";
    const std::string_view first = next_line();
    if (first.substr(0, kMagic.size()) != kMagic)
      fail_at(0, "not a VTK legacy file: the first line must be '# vtk DataFile Version <x.y>'");
    int major = 0;
    const std::string_view version = trimmed(first.substr(kMagic.size()));  // VTK's sscanf skips spaces
    const auto [end, ec] = std::from_chars(version.data(), version.data() + version.size(), major);
    if (ec != std::errc{} || end == version.data() || major < 1)
      fail_at(0, "the version " + quoted(version) + " on the first line is not a number");
    offsets_layout_ = major >= 5;
    next_line();  // the title (where 3D Slicer says SPACE=LPS or SPACE=RAS: mesh_space.cpp)
    const std::size_t encoding_at = pos_;
    if (pos_ >= s_.size()) fail_at(pos_, "the file ends before its third line (ASCII or BINARY)");
    const std::string_view encoding = trimmed(next_line());
    if (iequals(encoding, "BINARY"))
      binary_ = true;
    else if (!iequals(encoding, "ASCII"))
      fail_at(encoding_at, "the third line must be ASCII or BINARY, found " + quoted(encoding));
    expect("DATASET");
    const std::size_t kind_at = pos_;
    const std::string_view kind = word();
    if (!iequals(kind, "POLYDATA"))
      fail_at(kind_at, "only POLYDATA is read as a mesh; this file's dataset is " + quoted(kind));

    std::vector<double> points;
    bool have_points = false;
    std::vector<int> faces;
    for (;;) {
      const std::size_t at = skip_space();
      const std::string_view key = word();
      if (key.empty() || iequals(key, "POINT_DATA") || iequals(key, "CELL_DATA")) break;
      if (iequals(key, "POINTS")) {
        if (have_points) fail_at(at, "a second POINTS section");
        points = read_points();
        have_points = true;
      } else if (iequals(key, "POLYGONS") || iequals(key, "TRIANGLE_STRIPS") || iequals(key, "VERTICES") ||
                 iequals(key, "LINES")) {
        if (!have_points) fail_at(at, std::string(key) + " comes before POINTS");
        const Cells cells = read_cells(key, points.size() / 3);
        if (iequals(key, "POLYGONS")) add_polygons(cells, faces, at);
        if (iequals(key, "TRIANGLE_STRIPS")) add_strips(cells, faces);
      } else if (iequals(key, "FIELD")) {
        skip_field();
      } else if (iequals(key, "METADATA")) {
        skip_metadata(0);
      } else {
        fail_at(at, "unexpected " + quoted(key) +
                        " (a polydata section is POINTS, POLYGONS, TRIANGLE_STRIPS, VERTICES, LINES, FIELD, "
                        "METADATA, POINT_DATA or CELL_DATA)");
      }
    }
    if (!have_points) fail_at(pos_, "the file has no POINTS section");

    TriangleMesh mesh;
    mesh.V.resize(static_cast<Eigen::Index>(points.size() / 3), 3);
    std::copy(points.begin(), points.end(), mesh.V.data());
    mesh.F.resize(static_cast<Eigen::Index>(faces.size() / 3), 3);
    std::copy(faces.begin(), faces.end(), mesh.F.data());
    return {std::move(mesh), binary_ ? MeshFormat::VtkBinary : MeshFormat::VtkAscii};
  }

 private:
  // ---- text ----

  std::size_t skip_space() {
    while (pos_ < s_.size() && is_space(s_[pos_])) ++pos_;
    return pos_;
  }

  std::string_view word() {
    skip_space();
    const std::size_t start = pos_;
    while (pos_ < s_.size() && !is_space(s_[pos_])) ++pos_;
    return s_.substr(start, pos_ - start);
  }

  std::string_view next_line() {
    const std::size_t start = pos_;
    std::size_t end = s_.find('\n', pos_);
    if (end == std::string_view::npos) end = s_.size();
    pos_ = std::min(end + 1, s_.size());
    return s_.substr(start, end - start);
  }

  static std::string_view trimmed(std::string_view v) {
    while (!v.empty() && is_space(v.front())) v.remove_prefix(1);
    while (!v.empty() && is_space(v.back())) v.remove_suffix(1);
    return v;
  }

  void expect(std::string_view keyword) {
    const std::size_t at = skip_space();
    const std::string_view w = word();
    if (!iequals(w, keyword)) fail_at(at, "expected " + std::string(keyword) + ", found " + quoted(w));
  }

  bool next_is(std::string_view keyword) {
    const std::size_t at = skip_space();
    const bool is = iequals(word(), keyword);
    pos_ = at;
    return is;
  }

  // A count on a section's line: a whole number, at most what the rest of the file can hold
  // at `min_bytes` bytes a value (checked before anything is allocated).
  std::size_t count(std::string_view what, std::size_t values_per_item, std::size_t min_bytes) {
    const std::size_t at = skip_space();
    const std::string_view w = word();
    std::uint64_t n = 0;
    const auto [end, ec] = std::from_chars(w.data(), w.data() + w.size(), n);
    if (w.empty() || ec != std::errc{} || end != w.data() + w.size())
      fail_at(at, std::string(what) + " " + quoted(w) + " is not a whole number");
    const std::uint64_t left = s_.size() - pos_;
    if (n > left / std::max<std::size_t>(1, values_per_item * min_bytes))
      fail_at(at, std::string(what) + " " + std::to_string(n) + " cannot fit in the " + std::to_string(left) +
                      " bytes left in the file");
    return static_cast<std::size_t>(n);
  }

  ValueType type_word() {
    const std::size_t at = skip_space();
    const std::string_view w = word();
    const auto t = value_type(w);
    if (!t) fail_at(at, "unknown value type " + quoted(w));
    return *t;
  }

  // Where BINARY values start: right after the end of the line that announced them.
  void to_binary_data() {
    const std::size_t end = s_.find('\n', pos_);
    if (end == std::string_view::npos) fail_at(pos_, "the file ends before its binary values");
    pos_ = end + 1;
  }

  // ---- values ----

  // n values of type t as doubles (ASCII: any number; BINARY: big-endian of t's size).
  template <class T, class Check>
  std::vector<T> values(std::size_t n, const ValueType& t, std::string_view what, Check&& check) {
    std::vector<T> out;
    // ASCII counts are bounded only by the bytes left (two a value): grow as values come.
    out.reserve(binary_ ? n : std::min<std::size_t>(n, 1u << 20));
    if (binary_) {
      to_binary_data();
      if (n > (s_.size() - pos_) / t.bytes)
        fail_at(pos_, "the file ends inside its " + std::string(what) + " (" + std::to_string(n) + " values of " +
                          std::to_string(t.bytes) + " bytes)");
      for (std::size_t i = 0; i < n; ++i, pos_ += t.bytes) out.push_back(check(decode<T>(t), pos_));
      return out;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t at = skip_space();
      const std::string_view w = word();
      if (w.empty()) fail_at(at, "the file ends inside its " + std::string(what));
      T v{};
      if (parse_number(w, v) != NumberParse::Ok)
        fail_at(at, std::string(what) + ": " + quoted(w) +
                        (std::is_floating_point_v<T> ? " is not a number" : " is not an integer in range"));
      out.push_back(check(v, at));
    }
    return out;
  }

  // The value at pos_: big-endian bytes, put together by arithmetic (any host order).
  template <class T>
  T decode(const ValueType& t) const {
    std::uint64_t u = 0;
    for (std::size_t i = 0; i < t.bytes; ++i) u = (u << 8) | static_cast<unsigned char>(s_[pos_ + i]);
    if (t.kind == Kind::Floating)
      return static_cast<T>(t.bytes == 4 ? static_cast<double>(std::bit_cast<float>(static_cast<std::uint32_t>(u)))
                                         : std::bit_cast<double>(u));
    if (t.kind == Kind::Signed && t.bytes < 8 && ((u >> (8 * t.bytes - 1)) & 1u)) u |= ~std::uint64_t{0} << (8 * t.bytes);
    // As int64: an unsigned value past its range turns negative and is refused as an index.
    if (t.kind == Kind::Unsigned && std::is_floating_point_v<T>) return static_cast<T>(u);
    return static_cast<T>(static_cast<std::int64_t>(u));
  }

  std::vector<double> read_points() {
    const std::size_t n = count("POINTS count", 3, binary_ ? 1 : 2);
    const std::size_t type_at = skip_space();
    const ValueType t = type_word();
    if (binary_ && n > (s_.size() - pos_) / (3 * t.bytes))
      fail_at(type_at, "POINTS " + std::to_string(n) + " of " + std::to_string(t.bytes) +
                           " bytes each cannot fit in the rest of the file");
    std::size_t k = 0;
    auto finite = [&](double v, std::size_t at) {
      if (!std::isfinite(v))
        fail_at(at, "point " + std::to_string(k / 3) + " has a non-finite coordinate");
      ++k;
      return v;
    };
    std::vector<double> p = values<double>(3 * n, t, "POINTS", finite);
    skip_metadata_if_any(3);
    return p;
  }

  // Where value `index` of an array whose values start at `start` lies (its line in ASCII,
  // its byte in BINARY): found again only for an error, so no position is kept per value.
  std::size_t value_position(std::size_t start, std::size_t index, std::size_t bytes) const {
    if (binary_) {
      const std::size_t end = s_.find('\n', start);
      return end == std::string_view::npos ? start : end + 1 + index * bytes;
    }
    std::size_t at = start;
    for (std::size_t i = 0;; ++i) {
      while (at < s_.size() && is_space(s_[at])) ++at;
      if (i == index || at >= s_.size()) return at;
      while (at < s_.size() && !is_space(s_[at])) ++at;
    }
  }

  Cells read_cells(std::string_view key, std::size_t points) {
    const std::string section(key);
    Cells c;
    std::function<std::size_t(std::size_t cell, std::size_t index)> id_at;  // where c.ids[index] was
    auto integral = [&](const ValueType& t, std::size_t at) {
      if (t.kind == Kind::Floating) fail_at(at, section + ": cell indices must have an integer type");
    };
    auto any = [](std::int64_t v, std::size_t) { return v; };
    if (offsets_layout_) {
      // "KEY nOffsets nConnectivity", then OFFSETS and CONNECTIVITY arrays (version 5).
      const std::size_t n_offsets = count(section + " offset count", 1, binary_ ? 1 : 2);
      const std::size_t n_ids = count(section + " connectivity size", 1, binary_ ? 1 : 2);
      if (n_offsets == 0 && n_ids == 0 && !next_is("OFFSETS")) return c;  // VTK reads an empty section so
      expect("OFFSETS");
      const std::size_t at = skip_space();
      ValueType t = type_word();
      integral(t, at);
      std::vector<std::int64_t> offsets = values<std::int64_t>(n_offsets, t, section + " OFFSETS", any);
      skip_metadata_if_any(1);
      expect("CONNECTIVITY");
      const std::size_t ids_at = skip_space();
      t = type_word();
      integral(t, ids_at);
      const std::size_t ids_start = pos_;
      const std::size_t id_bytes = t.bytes;
      c.ids = values<std::int64_t>(n_ids, t, section + " CONNECTIVITY", any);
      id_at = [this, ids_start, id_bytes](std::size_t, std::size_t i) { return value_position(ids_start, i, id_bytes); };
      skip_metadata_if_any(1);
      if (offsets.empty()) {
        if (!c.ids.empty()) fail_at(ids_at, section + ": connectivity without offsets");
      } else {
        if (offsets.front() != 0) fail_at(at, section + ": the first offset is " + std::to_string(offsets.front()) + ", not 0");
        for (std::size_t i = 1; i < offsets.size(); ++i)
          if (offsets[i] < offsets[i - 1])
            fail_at(at, section + ": offset " + std::to_string(i) + " goes back (" + std::to_string(offsets[i]) +
                            " after " + std::to_string(offsets[i - 1]) + ")");
        if (offsets.back() != static_cast<std::int64_t>(c.ids.size()))
          fail_at(at, section + ": the last offset is " + std::to_string(offsets.back()) + " but there are " +
                          std::to_string(c.ids.size()) + " indices");
        c.offsets = std::move(offsets);
      }
    } else {
      // "KEY nCells size", then per cell its point count and indices (size values in all).
      const std::size_t n_cells = count(section + " cell count", 1, binary_ ? 4 : 2);
      const std::size_t size = count(section + " size", 1, binary_ ? 4 : 2);
      const std::size_t at = pos_;
      std::vector<std::int64_t> v = values<std::int64_t>(size, ValueType{4, Kind::Signed}, section, any);
      // Cell c's index i was value i + c + 1 of the section: each cell before it and this
      // one began with their point count.
      id_at = [this, at](std::size_t cell, std::size_t i) { return value_position(at, i + cell + 1, 4); };
      // Each cell's indices move down over the counts before them, in place: w <= p.
      std::size_t p = 0, w = 0;
      c.offsets.reserve(n_cells + 1);
      for (std::size_t cell = 0; cell < n_cells; ++cell) {
        if (p >= v.size())
          fail_at(at, section + ": declares " + std::to_string(n_cells) + " cells but its " + std::to_string(size) +
                          " values hold " + std::to_string(cell));
        const std::int64_t k = v[p++];
        if (k < 0 || static_cast<std::uint64_t>(k) > v.size() - p)
          fail_at(at, section + ": cell " + std::to_string(cell) + " says it has " + std::to_string(k) +
                          " points, more than the values left");
        for (std::int64_t j = 0; j < k; ++j) v[w++] = v[p++];
        c.offsets.push_back(static_cast<std::int64_t>(w));
      }
      if (p != v.size())
        fail_at(at, section + ": size " + std::to_string(size) + " but its " + std::to_string(n_cells) +
                        " cells use " + std::to_string(p) + " values");
      v.resize(w);
      c.ids = std::move(v);
      skip_metadata_if_any(1);
    }
    for (std::size_t cell = 0; cell < c.count(); ++cell)
      for (auto i = c.offsets[cell]; i < c.offsets[cell + 1]; ++i) {
        const std::int64_t id = c.ids[static_cast<std::size_t>(i)];
        if (id < 0 || static_cast<std::uint64_t>(id) >= points)
          fail_at(id_at(cell, static_cast<std::size_t>(i)), section + ": cell " + std::to_string(cell) + " has point index " + std::to_string(id) +
                            " but the file has " + std::to_string(points) + " points");
      }
    return c;
  }

  // Polygons with more than 3 corners are fan-triangulated (0,1,2), (0,2,3), ...
  void add_polygons(const Cells& c, std::vector<int>& faces, std::size_t at) const {
    faces.reserve(faces.size() + 3 * c.ids.size());  // a polygon of n corners gives n - 2 triangles
    for (std::size_t cell = 0; cell < c.count(); ++cell) {
      const auto first = static_cast<std::size_t>(c.offsets[cell]);
      const auto n = static_cast<std::size_t>(c.offsets[cell + 1]) - first;
      if (n < 3) fail_at(at, "POLYGONS: cell " + std::to_string(cell) + " has " + std::to_string(n) + " points; a face needs 3");
      for (std::size_t k = 1; k + 1 < n; ++k)
        for (const std::size_t j : {first, first + k, first + k + 1}) faces.push_back(static_cast<int>(c.ids[j]));
    }
  }

  // A strip (p0, p1, p2, p3, ...) is the triangles (p0,p1,p2), (p2,p1,p3), ... : every
  // second one turned so that all face the same way. Triangles with a repeated corner,
  // which join strips, have no area and are left out.
  static void add_strips(const Cells& c, std::vector<int>& faces) {
    faces.reserve(faces.size() + 3 * c.ids.size());
    for (std::size_t cell = 0; cell < c.count(); ++cell) {
      const auto first = static_cast<std::size_t>(c.offsets[cell]);
      const auto n = static_cast<std::size_t>(c.offsets[cell + 1]) - first;
      for (std::size_t k = 0; k + 2 < n; ++k) {
        std::int64_t a = c.ids[first + k], b = c.ids[first + k + 1];
        const std::int64_t d = c.ids[first + k + 2];
        if (k % 2 == 1) std::swap(a, b);
        if (a == b || b == d || a == d) continue;
        for (const std::int64_t v : {a, b, d}) faces.push_back(static_cast<int>(v));
      }
    }
  }

  // "FIELD name n", then n arrays "name components tuples type" with their values, which
  // are skipped unread (not kept: nothing is allocated for them).
  void skip_field() {
    word();  // the field's name
    const std::size_t arrays = count("FIELD array count", 1, 1);
    for (std::size_t a = 0; a < arrays; ++a) {
      const std::size_t at = skip_space();
      const std::string_view name = word();
      if (name.empty()) fail_at(at, "the file ends inside FIELD data");
      if (iequals(name, "NULL_ARRAY")) continue;
      const std::size_t components = count("FIELD array components", 1, 1);
      const std::size_t tuples = count("FIELD array tuples", 1, 1);
      const std::size_t type_at = skip_space();
      const std::string_view type_name = word();
      if (components != 0 && tuples > (s_.size() - pos_) / components)
        fail_at(type_at, "FIELD array " + quoted(name) + " cannot fit in the rest of the file");
      const std::size_t n = components * tuples;
      const auto t = value_type(type_name);
      const bool bits = iequals(type_name, "bit");
      const bool strings = iequals(type_name, "string") || iequals(type_name, "utf8_string");
      if ((t || bits) && binary_) {
        to_binary_data();
        const std::size_t bytes = bits ? (n + 7) / 8 : n;  // for t: values, below
        if (bytes > (s_.size() - pos_) / (bits ? 1 : t->bytes))
          fail_at(pos_, "the file ends inside FIELD array " + quoted(name));
        pos_ += bits ? bytes : n * t->bytes;
      } else if (t || bits) {
        for (std::size_t i = 0; i < n; ++i)
          if (word().empty()) fail_at(pos_, "the file ends inside FIELD array " + quoted(name));
      } else if (strings && binary_) {
        to_binary_data();
        for (std::size_t i = 0; i < n; ++i) skip_binary_string(name);
      } else if (strings) {
        next_line();  // the rest of the array's line; then a string a line
        for (std::size_t i = 0; i < n; ++i) {
          if (pos_ >= s_.size()) fail_at(pos_, "the file ends inside FIELD array " + quoted(name));
          next_line();
        }
      } else {
        fail_at(type_at, "FIELD array " + quoted(name) + " of type " + quoted(type_name) +
                             " cannot be skipped (numbers, bits and strings can)");
      }
      skip_metadata_if_any(components);
    }
  }

  // "METADATA", then COMPONENT_NAMES (a line a component, empty for an unnamed one) and
  // INFORMATION (its NAME and DATA lines), ended by an empty line: what VTK 8+ writes after
  // an array of `components` components (0: not known; then the names end at an empty line
  // too). A block that never ends takes the rest of the file, as in VTK's reader.
  void skip_metadata(std::size_t components) {
    next_line();  // the rest of the METADATA line
    while (pos_ < s_.size()) {
      const std::string_view line = trimmed(next_line());
      if (line.empty()) return;
      if (iequals(line, "COMPONENT_NAMES"))
        for (std::size_t i = 0; i < components && pos_ < s_.size(); ++i) next_line();
    }
  }

  void skip_metadata_if_any(std::size_t components) {
    const std::size_t at = skip_space();
    const std::string_view w = word();
    if (iequals(w, "METADATA"))
      skip_metadata(components);
    else
      pos_ = at;
  }

  // One string of a BINARY string array: a big-endian length whose first byte's top two
  // bits say its width (11: the byte's 6 bits, 10: 2 bytes, 01: 4, 00: 8), then the bytes.
  void skip_binary_string(std::string_view array) {
    if (pos_ >= s_.size()) fail_at(pos_, "the file ends inside FIELD array " + quoted(array));
    const auto first = static_cast<unsigned char>(s_[pos_]);
    static constexpr std::size_t kWidth[] = {8, 4, 2, 1};
    const std::size_t width = kWidth[first >> 6];
    if (s_.size() - pos_ < width) fail_at(pos_, "the file ends inside FIELD array " + quoted(array));
    std::uint64_t length = first & 0x3Fu;
    for (std::size_t i = 1; i < width; ++i) length = (length << 8) | static_cast<unsigned char>(s_[pos_ + i]);
    pos_ += width;
    if (length > s_.size() - pos_)
      fail_at(pos_, "a string of FIELD array " + quoted(array) + " is longer than the rest of the file");
    pos_ += static_cast<std::size_t>(length);
  }

  // ---- errors ----

  [[noreturn]] void fail_at(std::size_t at, const std::string& what) const {
    at = std::min(at, s_.size());
    if (!binary_) {
      const auto line = 1 + std::count(s_.begin(), s_.begin() + static_cast<std::ptrdiff_t>(at), '\n');
      fail(path_, "line " + std::to_string(line) + ": " + what);
    }
    fail(path_, "byte " + std::to_string(at) + ": " + what);
  }

  const std::filesystem::path& path_;
  std::string_view s_;
  std::size_t pos_ = 0;
  bool binary_ = false;
  bool offsets_layout_ = false;
};

template <class T>
void put_be(std::string& out, T value) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::little) reverse_bytes(b, sizeof(T));
  out.append(b, sizeof(T));
}

template <class T>
void put_text(std::string& out, T value) {
  char buf[32];
  const auto [ptr, ec] = [&] {
    if constexpr (std::is_floating_point_v<T>)
      return std::to_chars(buf, buf + sizeof buf, value, std::chars_format::general, 17);
    else
      return std::to_chars(buf, buf + sizeof buf, value);
  }();
  out.append(buf, ec == std::errc{} ? ptr : buf);
}

}  // namespace

LoadedMesh read_vtk(const std::filesystem::path& path, std::string_view bytes) { return VtkReader(path, bytes).read(); }

// Version 4.2, as 3D Slicer writes for the widest compatibility; double coordinates, so
// a round trip is exact.
void write_vtk(const std::filesystem::path& path, const TriangleMesh& mesh, bool binary, std::string_view space_tag) {
  check_indices_for_writing(mesh, path);
  const auto nv = mesh.V.rows();
  const auto nf = mesh.F.rows();
  std::string out;
  out.reserve(256 + static_cast<std::size_t>(nv) * (binary ? 24 : 60) + static_cast<std::size_t>(nf) * (binary ? 16 : 30));
  out += "# vtk DataFile Version 4.2\nevarnode ";
  out += space_tag;
  out += binary ? "\nBINARY\n" : "\nASCII\n";
  out += "DATASET POLYDATA\nPOINTS " + std::to_string(nv) + " double\n";
  for (Eigen::Index v = 0; v < nv; ++v)
    for (int k = 0; k < 3; ++k) {
      if (binary) {
        put_be(out, mesh.V(v, k));
      } else {
        put_text(out, mesh.V(v, k));
        out += k == 2 ? '\n' : ' ';
      }
    }
  if (binary) out += '\n';
  out += "POLYGONS " + std::to_string(nf) + " " + std::to_string(4 * nf) + "\n";
  for (Eigen::Index f = 0; f < nf; ++f) {
    if (binary) {
      put_be(out, std::int32_t{3});
      for (int k = 0; k < 3; ++k) put_be(out, std::int32_t{mesh.F(f, k)});
    } else {
      out += '3';
      for (int k = 0; k < 3; ++k) {
        out += ' ';
        put_text(out, mesh.F(f, k));
      }
      out += '\n';
    }
  }
  if (binary) out += '\n';
  base::write_file_atomically(path, out);
}

}  // namespace evar::geometry::detail

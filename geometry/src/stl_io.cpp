// STL: binary through assimp (no post-processing), ASCII through our own parser, both
// welded into an indexed mesh. Written directly (binary or ASCII).
//
// Why ASCII STL is not read by assimp 5.2: its number parser is not correctly rounded
// (of 9000 vertices with random float coordinates printed with %.9g, 259 came back with a
// coordinate 1 ulp off, so an ASCII round trip is not exact), it silently accepts
// malformed facets (a facet with 4 vertices loses the 4th), and its errors carry no line
// number. from_chars is exact.
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cctype>
#include <cstring>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include <assimp/Importer.hpp>
#include <assimp/scene.h>

#include "mesh_formats.hpp"
#include "evar/base/atomic_file.hpp"

namespace evar::geometry::detail {

namespace {

constexpr std::size_t kHeaderBytes = 80;
constexpr std::size_t kPreambleBytes = kHeaderBytes + 4;  // header + triangle count
constexpr std::size_t kTriangleBytes = 50;  // normal, 3 vertices (12 floats), attribute

// ---- welding -----------------------------------------------------------------------

// Identical float values become one vertex, numbered in order of first appearance.
// -0 and +0 are folded together (they compare equal and are the same point).
class Welder {
 public:
  explicit Welder(std::size_t triangles) {
    index_.reserve(triangles);  // closed meshes have about half as many vertices as faces
    faces_.reserve(triangles * 3);
  }

  void add_corner(const std::array<float, 3>& p) {
    Key key{};
    for (int k = 0; k < 3; ++k) key.bits[k] = std::bit_cast<std::uint32_t>(p[k] + 0.0f);
    const auto [it, inserted] = index_.try_emplace(key, static_cast<int>(positions_.size() / 3));
    if (inserted) positions_.insert(positions_.end(), p.begin(), p.end());
    faces_.push_back(it->second);
  }

  TriangleMesh mesh() const {
    TriangleMesh m;
    m.V.resize(static_cast<Eigen::Index>(positions_.size() / 3), 3);
    for (std::size_t i = 0; i < positions_.size(); ++i) m.V.data()[i] = positions_[i];
    // A sliver whose corners weld together has no area and no orientation: segmentation
    // exports contain them, so they are dropped here rather than refused later.
    std::vector<int> kept;
    kept.reserve(faces_.size());
    for (std::size_t f = 0; f + 2 < faces_.size(); f += 3) {
      const int a = faces_[f], b = faces_[f + 1], c = faces_[f + 2];
      if (a == b || b == c || a == c) continue;
      kept.insert(kept.end(), {a, b, c});
    }
    m.F.resize(static_cast<Eigen::Index>(kept.size() / 3), 3);
    std::copy(kept.begin(), kept.end(), m.F.data());
    return m;
  }

 private:
  struct Key {
    std::array<std::uint32_t, 3> bits;
    bool operator==(const Key&) const = default;
  };
  struct KeyHash {
    std::size_t operator()(const Key& k) const noexcept {
      std::uint64_t h = 1469598103934665603ull;  // FNV-1a over the three words
      for (std::uint32_t w : k.bits) h = (h ^ w) * 1099511628211ull;
      return static_cast<std::size_t>(h ^ (h >> 32));
    }
  };
  std::unordered_map<Key, int, KeyHash> index_;
  std::vector<float> positions_;
  std::vector<int> faces_;
};

// ---- ASCII -------------------------------------------------------------------------

class AsciiStlParser {
 public:
  AsciiStlParser(const std::filesystem::path& path, std::string_view text)
      : path_(path), text_(text) {}

  TriangleMesh parse() {
    // Count facets first so the welder can reserve, and to bound the size.
    std::size_t facets = 0;
    for (std::size_t p = text_.find("endloop"); p != std::string_view::npos;
         p = text_.find("endloop", p + 7)) {
      ++facets;
    }
    Welder welder(facets);

    expect("solid");
    skip_line();
    std::size_t triangles = 0;
    for (;;) {
      const std::string_view tok = next();
      if (tok.empty()) fail_here("file ends without 'endsolid' (truncated?)");
      if (iequals(tok, "endsolid")) {
        skip_line();
        const std::string_view after = next();
        if (after.empty()) break;
        if (!iequals(after, "solid")) {
          fail_here("expected 'solid' or the end of the file after 'endsolid', found " +
                    quoted(after));
        }
        skip_line();  // several solids in one file are concatenated
        continue;
      }
      if (!iequals(tok, "facet")) fail_here("expected 'facet' or 'endsolid', found " + quoted(tok));
      expect("normal");
      for (int k = 0; k < 3; ++k) number("normal component");  // recomputed, value unused
      expect("outer");
      expect("loop");
      for (int corner = 0; corner < 3; ++corner) {
        const std::string_view v = next();
        if (!iequals(v, "vertex")) {
          fail_here("facet " + std::to_string(triangles) + " has " + std::to_string(corner) +
                    " vertices; expected 'vertex', found " + quoted(v));
        }
        std::array<float, 3> p{};
        for (int k = 0; k < 3; ++k) {
          p[k] = number("vertex coordinate");
          if (!std::isfinite(p[k])) fail_here("vertex coordinate is not finite");
        }
        welder.add_corner(p);
      }
      const std::string_view end_loop = next();
      if (iequals(end_loop, "vertex")) {
        fail_here("facet " + std::to_string(triangles) + " has more than 3 vertices");
      }
      if (!iequals(end_loop, "endloop")) fail_here("expected 'endloop', found " + quoted(end_loop));
      expect("endfacet");
      if (++triangles > static_cast<std::size_t>(std::numeric_limits<int>::max() / 3)) {
        fail_here("too many triangles");
      }
    }
    return welder.mesh();
  }

 private:
  [[noreturn]] void fail_here(const std::string& what) const {
    fail(path_, "line " + std::to_string(token_line_) + ": " + what);
  }

  // Next whitespace-separated token (empty at end of file); tracks its line number.
  std::string_view next() {
    while (pos_ < text_.size() && is_space(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    token_line_ = line_;
    const std::size_t start = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
    return text_.substr(start, pos_ - start);
  }

  void skip_line() {
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
  }

  void expect(std::string_view keyword) {
    const std::string_view tok = next();
    if (!iequals(tok, keyword)) {
      fail_here("expected '" + std::string(keyword) + "', found " +
                (tok.empty() ? std::string("the end of the file") : quoted(tok)));
    }
  }

  float number(const char* what) {
    const std::string_view tok = next();
    if (tok.empty()) fail_here(std::string("file ends where a ") + what + " was expected");
    float value = 0.0f;
    switch (parse_number(tok, value)) {
      case NumberParse::Ok: return value;
      case NumberParse::OutOfRange:
        fail_here(std::string(what) + " " + quoted(tok) + " is out of range for a float");
      case NumberParse::NotANumber: break;
    }
    fail_here(std::string(what) + " " + quoted(tok) + " is not a number");
  }

  const std::filesystem::path& path_;
  std::string_view text_;
  std::size_t pos_ = 0;
  std::size_t line_ = 1;
  std::size_t token_line_ = 1;
};

bool starts_with_solid(std::string_view bytes) {
  std::size_t p = 0;
  while (p < bytes.size() && is_space(bytes[p])) ++p;
  return bytes.size() - p >= 5 && iequals(bytes.substr(p, 5), "solid");
}

// ---- binary ------------------------------------------------------------------------

std::uint32_t load_u32_le(const char* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  if constexpr (std::endian::native == std::endian::big) reverse_bytes(&v, 4);
  return v;
}

TriangleMesh read_binary(const std::filesystem::path& path, std::string_view bytes,
                         std::uint32_t triangles) {
  if (triangles == 0) return {};  // a valid, empty file; assimp refuses those
  if (triangles > static_cast<std::uint32_t>(std::numeric_limits<int>::max() / 3)) {
    fail(path, "binary STL declares " + std::to_string(triangles) + " triangles: too many");
  }
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFileFromMemory(bytes.data(), bytes.size(), 0u, "stl");
  if (scene == nullptr) {
    fail(path, std::string("binary STL could not be read: ") + importer.GetErrorString());
  }

  Welder welder(triangles);
  std::size_t t = 0;  // triangle index in file order, for byte offsets in messages
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    for (unsigned f = 0; f < mesh->mNumFaces; ++f, ++t) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) {
        fail(path, "byte " + std::to_string(kPreambleBytes + t * kTriangleBytes) + ": triangle " +
                       std::to_string(t) + " came back from assimp with " +
                       std::to_string(face.mNumIndices) + " corners");
      }
      for (unsigned k = 0; k < 3; ++k) {
        const unsigned i = face.mIndices[k];
        if (i >= mesh->mNumVertices) fail(path, "assimp returned a vertex index out of range");
        const aiVector3D& v = mesh->mVertices[i];
        const std::array<float, 3> p{static_cast<float>(v.x), static_cast<float>(v.y),
                                     static_cast<float>(v.z)};
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
          const std::size_t at = kPreambleBytes + t * kTriangleBytes + 12 + 12 * k;
          fail(path, "byte " + std::to_string(at) + ": triangle " + std::to_string(t) +
                         " vertex " + std::to_string(k) + " has a non-finite coordinate");
        }
        welder.add_corner(p);
      }
    }
  }
  if (t != triangles) {
    fail(path, "binary STL declares " + std::to_string(triangles) + " triangles but " +
                   std::to_string(t) + " were read");
  }
  return welder.mesh();
}

// ---- writing -----------------------------------------------------------------------

void put_f32_le(std::string& out, float value) {
  auto bits = std::bit_cast<std::uint32_t>(value);
  if constexpr (std::endian::native == std::endian::big) reverse_bytes(&bits, 4);
  char b[4];
  std::memcpy(b, &bits, 4);
  out.append(b, 4);
}

void put_u32_le(std::string& out, std::uint32_t value) {
  if constexpr (std::endian::native == std::endian::big) reverse_bytes(&value, 4);
  char b[4];
  std::memcpy(b, &value, 4);
  out.append(b, 4);
}

void put_float_text(std::string& out, float value) {
  char buf[32];
  // Shortest text that reads back as exactly this float.
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, value);
  out.append(buf, ec == std::errc{} ? ptr : buf);
}

Eigen::Vector3f face_normal(const TriangleMesh& mesh, Eigen::Index f) {
  const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose();
  const Eigen::Vector3d b = mesh.V.row(mesh.F(f, 1)).transpose();
  const Eigen::Vector3d c = mesh.V.row(mesh.F(f, 2)).transpose();
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double len = n.norm();
  if (!(len > 0.0) || !std::isfinite(len)) return Eigen::Vector3f::Zero();  // degenerate
  return (n / len).cast<float>();
}

}  // namespace

LoadedMesh read_stl(const std::filesystem::path& path, std::string_view bytes) {
  // Binary layout: 80-byte header, uint32 count n, n * 50 bytes. Files whose size fits
  // that rule are binary unless they also start with "solid" and parse as ASCII
  // (many binary writers put "solid" at the start of the header).
  std::uint32_t declared = 0;
  bool binary_size_ok = false;
  if (bytes.size() >= kPreambleBytes) {
    declared = load_u32_le(bytes.data() + kHeaderBytes);
    binary_size_ok = kPreambleBytes + std::uint64_t{declared} * kTriangleBytes == bytes.size();
  }
  // ASCII STL never contains a NUL byte; binary headers and counts nearly always do.
  const bool looks_binary = bytes.substr(0, 1024).find('\0') != std::string_view::npos;
  if (starts_with_solid(bytes)) {
    try {
      return {AsciiStlParser(path, bytes).parse(), MeshFormat::StlAscii};
    } catch (const base::InputError&) {
      // A damaged binary file whose header says "solid" is better reported as binary.
      if (!binary_size_ok && !looks_binary) throw;
    }
  }
  if (binary_size_ok) return {read_binary(path, bytes, declared), MeshFormat::StlBinary};
  if (bytes.size() < kPreambleBytes) {
    fail(path, "not an STL file: " + std::to_string(bytes.size()) +
                   " bytes is too short for binary STL and it does not start with 'solid'");
  }
  fail(path, "binary STL is truncated or has trailing data: the header at byte 80 declares " +
                 std::to_string(declared) + " triangles, which needs " +
                 std::to_string(kPreambleBytes + std::uint64_t{declared} * kTriangleBytes) +
                 " bytes, but the file has " + std::to_string(bytes.size()));
}

void write_stl(const std::filesystem::path& path, const TriangleMesh& mesh, bool binary, std::string_view space_tag) {
  check_indices_for_writing(mesh, path);
  const auto nf = static_cast<std::size_t>(mesh.F.rows());
  std::string out;
  if (binary) {
    out.reserve(kPreambleBytes + nf * kTriangleBytes);
    // Must not start with "solid": other readers would take the file for ASCII.
    std::string header = "evarnode binary STL ";
    header += space_tag;
    header.resize(kHeaderBytes, ' ');
    out += header;
    put_u32_le(out, static_cast<std::uint32_t>(nf));
    for (std::size_t f = 0; f < nf; ++f) {
      const auto fi = static_cast<Eigen::Index>(f);
      const Eigen::Vector3f n = face_normal(mesh, fi);
      for (int k = 0; k < 3; ++k) put_f32_le(out, n[k]);
      for (int c = 0; c < 3; ++c) {
        for (int k = 0; k < 3; ++k) put_f32_le(out, static_cast<float>(mesh.V(mesh.F(fi, c), k)));
      }
      out.append(2, '\0');  // attribute byte count
    }
  } else {
    out.reserve(64 + nf * 200);
    out += "solid evarnode ";
    out += space_tag;
    out += '\n';
    for (std::size_t f = 0; f < nf; ++f) {
      const auto fi = static_cast<Eigen::Index>(f);
      const Eigen::Vector3f n = face_normal(mesh, fi);
      out += "  facet normal";
      for (int k = 0; k < 3; ++k) {
        out += ' ';
        put_float_text(out, n[k]);
      }
      out += "\n    outer loop\n";
      for (int c = 0; c < 3; ++c) {
        out += "      vertex";
        for (int k = 0; k < 3; ++k) {
          out += ' ';
          put_float_text(out, static_cast<float>(mesh.V(mesh.F(fi, c), k)));
        }
        out += '\n';
      }
      out += "    endloop\n  endfacet\n";
    }
    out += "endsolid evarnode\n";
  }
  base::write_file_atomically(path, out);
}

}  // namespace evar::geometry::detail

// Wavefront OBJ, hand-written: assimp 5.2 de-indexes OBJ (one vertex per face corner,
// reordered, isolated vertices dropped); we need the file's vertex order and indices.
//
// Reads "v x y z [w]" and "f" with corners i, i/j, i//k, i/j/k, 1-based or negative
// (relative to the vertices read so far); polygons are fan-triangulated. Every other
// statement (vn, vt, g, o, s, usemtl, mtllib, l, comments, ...) is ignored.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "mesh_formats.hpp"
#include "evar/base/atomic_file.hpp"

namespace evar::geometry::detail {

namespace {

class LineWords {
 public:
  explicit LineWords(std::string_view line) : line_(line) {}
  std::string_view next() {
    while (pos_ < line_.size() && is_space(line_[pos_])) ++pos_;
    const std::size_t start = pos_;
    while (pos_ < line_.size() && !is_space(line_[pos_])) ++pos_;
    return line_.substr(start, pos_ - start);
  }

 private:
  std::string_view line_;
  std::size_t pos_ = 0;
};

}  // namespace

TriangleMesh read_obj(const std::filesystem::path& path, std::string_view bytes) {
  std::vector<double> positions;
  std::vector<int> faces;
  std::vector<int> polygon;
  // Positive indices may refer to vertices defined later in the file, so they are
  // range-checked at the end; we remember the worst one and its line.
  std::int64_t max_index = 0;
  std::size_t max_index_line = 0;

  std::size_t pos = 0;
  std::size_t line_no = 0;
  while (pos < bytes.size()) {
    std::size_t end = bytes.find('\n', pos);
    if (end == std::string_view::npos) end = bytes.size();
    const std::string_view line = bytes.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    auto bad = [&](const std::string& what) {
      fail(path, "line " + std::to_string(line_no) + ": " + what);
    };

    LineWords words(line);
    const std::string_view key = words.next();
    if (key == "v") {
      double xyz[3];
      for (double& c : xyz) {
        const std::string_view tok = words.next();
        if (tok.empty()) bad("vertex needs 3 coordinates");
        const NumberParse r = parse_number(tok, c);
        if (r == NumberParse::OutOfRange) bad("coordinate " + quoted(tok) + " is out of range");
        if (r != NumberParse::Ok) bad("coordinate " + quoted(tok) + " is not a number");
        if (!std::isfinite(c)) bad("coordinate " + quoted(tok) + " is not finite");
      }
      // Optional w, or the common "v x y z r g b" colour extension: numbers, ignored.
      for (std::string_view tok = words.next(); !tok.empty(); tok = words.next()) {
        double ignored = 0.0;
        if (parse_number(tok, ignored) != NumberParse::Ok) {
          bad("unexpected " + quoted(tok) + " after the vertex coordinates");
        }
      }
      if (positions.size() / 3 >= static_cast<std::size_t>(std::numeric_limits<int>::max())) {
        bad("too many vertices");
      }
      positions.insert(positions.end(), {xyz[0], xyz[1], xyz[2]});
    } else if (key == "f") {
      const auto nv = static_cast<std::int64_t>(positions.size() / 3);
      polygon.clear();
      for (std::string_view tok = words.next(); !tok.empty(); tok = words.next()) {
        // Only the part before the first '/' is the vertex index (then texture, normal).
        const std::string_view index_text = tok.substr(0, tok.find('/'));
        std::int64_t index = 0;
        if (parse_number(index_text, index) != NumberParse::Ok) {
          bad("face corner " + quoted(tok) + " does not start with an integer vertex index");
        }
        if (index == 0) bad("face corner " + quoted(tok) + ": vertex index 0 (OBJ counts from 1)");
        if (index < 0) {
          index += nv;  // -1 is the last vertex read so far
          if (index < 0) {
            bad("face corner " + quoted(tok) + " refers back past the first vertex (only " +
                std::to_string(nv) + " vertices so far)");
          }
        } else {
          index -= 1;
          if (index >= std::numeric_limits<int>::max()) bad("vertex index " + quoted(tok) + " is too large");
          if (index + 1 > max_index) {
            max_index = index + 1;
            max_index_line = line_no;
          }
        }
        polygon.push_back(static_cast<int>(index));
      }
      if (polygon.size() < 3) {
        bad("face has " + std::to_string(polygon.size()) + " vertices; a polygon needs at least 3");
      }
      for (std::size_t k = 2; k < polygon.size(); ++k) {
        faces.insert(faces.end(), {polygon[0], polygon[k - 1], polygon[k]});  // fan
      }
      if (faces.size() / 3 > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
        bad("too many faces");
      }
    }
  }

  const auto nv = static_cast<std::int64_t>(positions.size() / 3);
  if (max_index > nv) {
    fail(path, "line " + std::to_string(max_index_line) + ": face refers to vertex " +
                   std::to_string(max_index) + " but the file has " + std::to_string(nv) +
                   " vertices");
  }

  TriangleMesh mesh;
  mesh.V.resize(static_cast<Eigen::Index>(nv), 3);
  std::copy(positions.begin(), positions.end(), mesh.V.data());
  mesh.F.resize(static_cast<Eigen::Index>(faces.size() / 3), 3);
  std::copy(faces.begin(), faces.end(), mesh.F.data());
  return mesh;
}

void write_obj(const std::filesystem::path& path, const TriangleMesh& mesh, std::string_view space_tag) {
  check_indices_for_writing(mesh, path);
  std::string out;
  out.reserve(64 + static_cast<std::size_t>(mesh.V.rows()) * 60 +
              static_cast<std::size_t>(mesh.F.rows()) * 24);
  out += "# evarnode: millimetres, ";
  out += space_tag;
  out += '\n';
  char buf[32];
  // to_chars rather than printf: the same "%.17g" digits, but immune to the C locale's
  // decimal separator. 17 significant digits read back as exactly the same double.
  auto put = [&](auto value, auto... format) {
    const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, value, format...);
    out.append(buf, ec == std::errc{} ? ptr : buf);
  };
  for (Eigen::Index v = 0; v < mesh.V.rows(); ++v) {
    out += 'v';
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      put(mesh.V(v, k), std::chars_format::general, 17);
    }
    out += '\n';
  }
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    out += 'f';
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      put(mesh.F(f, k) + 1);
    }
    out += '\n';
  }
  base::write_file_atomically(path, out);
}

}  // namespace evar::geometry::detail

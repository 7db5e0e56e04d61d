// The coordinate system a mesh file declares. 3D Slicer (since 4.11) writes "SPACE=LPS"
// or "SPACE=RAS" into the header of every mesh file it saves: the binary STL header or the
// ASCII STL's solid line, a PLY comment, the OBJ's leading comment, a VTK file's title. It reads files back
// by searching those places for the two tags, and takes a file without one as LPS. We do
// the same, so a model saved from Slicer in RAS is not mirrored through the patient's
// long axis (x and y negated: left-right and front-back swapped).
#include <string>
#include <string_view>

#include "mesh_formats.hpp"

namespace evar::geometry::detail {

namespace {

constexpr std::string_view kLps = "SPACE=LPS";
constexpr std::string_view kRas = "SPACE=RAS";

struct Tags {
  bool lps = false, ras = false;
  void look_in(std::string_view text) {
    lps |= text.find(kLps) != std::string_view::npos;
    ras |= text.find(kRas) != std::string_view::npos;
  }
};

// Calls `line(text)` for each line of `bytes` (without its end) until it returns false.
template <class F>
void for_each_line(std::string_view bytes, F&& line) {
  std::size_t at = 0;
  while (at < bytes.size()) {
    std::size_t end = bytes.find('\n', at);
    if (end == std::string_view::npos) end = bytes.size();
    if (!line(bytes.substr(at, end - at))) return;
    at = end + 1;
  }
}

std::string_view trimmed_front(std::string_view s) {
  std::size_t p = 0;
  while (p < s.size() && is_space(s[p])) ++p;
  return s.substr(p);
}

bool starts_with_word(std::string_view line, std::string_view word) {
  return line.substr(0, word.size()) == word && (line.size() == word.size() || is_space(line[word.size()]));
}

}  // namespace

MeshSpace declared_space(const std::filesystem::path& path, std::string_view bytes, MeshFormat format) {
  Tags tags;
  switch (format) {
    case MeshFormat::StlBinary: {  // the 80-byte header, as a C string (VTK's reader stops at a NUL)
      const std::string_view header = bytes.substr(0, 80);
      tags.look_in(header.substr(0, header.find('\0')));
      break;
    }
    case MeshFormat::StlAscii:  // every solid's name: VTK's reader joins them into its header
      for_each_line(bytes, [&](std::string_view line) {
        line = trimmed_front(line);
        if (line.size() >= 5 && (line.substr(0, 5) == "solid" || line.substr(0, 5) == "SOLID")) tags.look_in(line);
        return true;
      });
      break;
    case MeshFormat::PlyAscii:
    case MeshFormat::PlyBinary:
      // The header is text up to end_header, which the reader has already found.
      for_each_line(bytes, [&](std::string_view line) {
        line = trimmed_front(line);
        if (starts_with_word(line, "comment")) tags.look_in(line);
        return !starts_with_word(line, "end_header");
      });
      break;
    case MeshFormat::Obj:
      // The comment lines from the first line on, without a break, as VTK's OBJ reader
      // gathers them (a blank line ends them).
      for_each_line(bytes, [&](std::string_view line) {
        line = trimmed_front(line);
        if (line.empty() || line.front() != '#') return false;
        tags.look_in(line);
        return true;
      });
      break;
    case MeshFormat::Vtp:  // its field data, read by read_vtp
      break;
    case MeshFormat::VtkAscii:
    case MeshFormat::VtkBinary: {  // the title, the second line
      const std::size_t first_end = bytes.find('\n');
      if (first_end != std::string_view::npos) {
        const std::string_view rest = bytes.substr(first_end + 1);
        tags.look_in(rest.substr(0, rest.find('\n')));
      }
      break;
    }
  }
  if (tags.lps && tags.ras)
    fail(path, "its header declares both " + std::string(kLps) + " and " + std::string(kRas) +
                   ": which coordinate system the points are in cannot be told");
  return tags.ras ? MeshSpace::Ras : tags.lps ? MeshSpace::Lps : MeshSpace::Undeclared;
}

void flip_lps_ras(TriangleMesh& mesh) {
  // Row by row: a mesh without vertices has no storage, and a column of it would be a
  // block of a null pointer (found by fuzz_mesh: an OBJ saying SPACE=RAS and nothing else).
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i) {
    mesh.V(i, 0) = -mesh.V(i, 0);
    mesh.V(i, 1) = -mesh.V(i, 1);
  }
}

std::string_view space_tag(MeshSpace space) { return space == MeshSpace::Ras ? kRas : kLps; }

}  // namespace evar::geometry::detail

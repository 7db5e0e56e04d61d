#pragma once
// Private to evar_geometry: the per-format readers and writers behind mesh_io.hpp, and
// the few helpers they share (whole-file reading, error messages that name the file).
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>

#include "evar/base/input_error.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::geometry::detail {

/// Reverses the bytes of one binary value in place (endianness conversion; C++20 has no
/// std::byteswap yet).
inline void reverse_bytes(void* value, std::size_t size) {
  auto* b = static_cast<unsigned char*>(value);
  std::reverse(b, b + size);
}

/// ASCII case-insensitive equality (format keywords: STL's, VTK's).
inline bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

inline bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v';
}

/// A token quoted for an error message: at most 24 characters, non-printable bytes shown
/// as '?' so binary junk cannot garble a terminal or a log.
std::string quoted(std::string_view token);

enum class NumberParse { Ok, NotANumber, OutOfRange };

/// The whole token as one number of type T (from_chars: exact, correctly rounded, locale
/// independent; "nan" and "inf" are accepted so the caller can name them). A single
/// leading '+' is allowed.
template <class T>
NumberParse parse_number(std::string_view token, T& value) {
  if (token.size() > 1 && token[0] == '+' && token[1] != '-') token.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec == std::errc::result_out_of_range) return NumberParse::OutOfRange;
  if (ec != std::errc{} || ptr != token.data() + token.size() || token.empty()) {
    return NumberParse::NotANumber;
  }
  return NumberParse::Ok;
}

/// Throws InputError "<path>: <what>".
[[noreturn]] void fail(const std::filesystem::path& path, const std::string& what);

/// std::invalid_argument if a face index is outside [0, #V): writers index V with them.
void check_indices_for_writing(const TriangleMesh& mesh, const std::filesystem::path& path);

/// `bytes` is the whole file; `path` is only used in error messages.
LoadedMesh read_stl(const std::filesystem::path& path, std::string_view bytes);
LoadedMesh read_ply(const std::filesystem::path& path, std::string_view bytes);
TriangleMesh read_obj(const std::filesystem::path& path, std::string_view bytes);
LoadedMesh read_vtk(const std::filesystem::path& path, std::string_view bytes);

/// What the file's header declares (mesh_space.cpp): the binary STL header, the ASCII STL's
/// first line, the PLY header's comments, the OBJ's leading comment lines or the VTK title, searched for
/// SPACE=RAS and SPACE=LPS as 3D Slicer does. InputError if it declares both.
MeshSpace declared_space(const std::filesystem::path& path, std::string_view bytes, MeshFormat format);

/// LPS <-> RAS: x and y negated (the change is its own inverse).
void flip_lps_ras(TriangleMesh& mesh);

/// "SPACE=LPS" or "SPACE=RAS", as 3D Slicer writes it (Undeclared: LPS).
std::string_view space_tag(MeshSpace space);

/// `space_tag` goes into the header: the binary STL header or solid line, a PLY comment,
/// the OBJ's first comment line. The coordinates are written as they are.
void write_stl(const std::filesystem::path& path, const TriangleMesh& mesh, bool binary, std::string_view space_tag);
void write_ply(const std::filesystem::path& path, const TriangleMesh& mesh, bool binary, std::string_view space_tag);
void write_obj(const std::filesystem::path& path, const TriangleMesh& mesh, std::string_view space_tag);
void write_vtk(const std::filesystem::path& path, const TriangleMesh& mesh, bool binary, std::string_view space_tag);

}  // namespace evar::geometry::detail

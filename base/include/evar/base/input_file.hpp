#pragma once
// Reading the node's file inputs with a size limit per kind of file. A file far larger
// than any real one of its kind (a wrong path, /dev/zero behind a symlink, a hostile
// upload) is refused before it is read, with an InputError naming the file, its size and
// the limit, so it cannot exhaust the bedside box's memory.
#include <cstdint>
#include <filesystem>
#include <string>

namespace evar::base {

struct InputLimit {
  std::uintmax_t bytes;  ///< largest accepted file size
  const char* kind;      ///< for the message: "a JSON file", "a mesh file", ...
};

inline constexpr std::uintmax_t kMiB = std::uintmax_t{1} << 20;
/// Scene, markups, view geometry, registration, node.json, session.json, ARAP constraints:
/// the largest real one (a dense centerline) is well under 1 MiB.
inline constexpr InputLimit kJsonLimit{64 * kMiB, "a JSON file"};
/// STL/PLY/OBJ: a 5-million-triangle binary STL is 240 MiB; an ASCII one about 4x that.
inline constexpr InputLimit kMeshLimit{1024 * kMiB, "a mesh file"};
/// Session index and C-arm CSV tables: an hour at 30 Hz is about 10 MiB.
inline constexpr InputLimit kTableLimit{256 * kMiB, "a CSV table"};
/// One fluoroscopy image (PNG, TIFF): 16-bit 4096 x 4096 uncompressed is 32 MiB.
inline constexpr InputLimit kImageLimit{256 * kMiB, "an image file"};
/// A DICOM XA series in one file: 1000 frames of 1024 x 1024 at 16 bits is 2 GiB.
inline constexpr InputLimit kDicomLimit{4096 * kMiB, "a DICOM file"};

/// InputError "<file>: ..." unless `file` is a regular file (not missing, not a directory,
/// FIFO or device: those might never end) of at most limit.bytes.
void check_input_file(const std::filesystem::path& file, InputLimit limit);

/// The whole file as bytes, after check_input_file; the limit is enforced while reading
/// too, since the file may grow under us.
std::string read_input_file(const std::filesystem::path& file, InputLimit limit);

}  // namespace evar::base

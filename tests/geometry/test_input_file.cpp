// Size limits of file inputs (issue 7): a file larger than any real one of its kind is
// refused before it is read, with an InputError naming the file, its size and the limit;
// something that is not a regular file (a FIFO would block forever) is refused too.
// Oversized files are sparse (resize_file), so the tests cost no disk and little time.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "evar/base/input_error.hpp"
#include "evar/base/input_file.hpp"
#include "evar/geometry/json_fields.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/xa_dicom.hpp"
#include "support/error_message.hpp"
#include "support/temp_dir.hpp"

namespace fs = std::filesystem;
using namespace evar::geometry;
using testing::HasSubstr;

namespace {

using evar::test::TempDir;

fs::path sparse_file(const fs::path& file, std::uintmax_t bytes) {
  std::ofstream(file) << "{";
  fs::resize_file(file, bytes);
  return file;
}

template <class F>
std::string error_of(F&& read) {
  return evar::test::error_message(std::forward<F>(read));
}

}  // namespace

TEST(InputFile, AJsonFileOverItsLimitIsRefusedByNameBeforeParsing) {
  TempDir dir;
  const auto file = sparse_file(dir.path / "huge.mrk.json", evar::base::kJsonLimit.bytes + 1);
  const std::string message = error_of([&] { read_curve(file); });
  EXPECT_THAT(message, HasSubstr("huge.mrk.json: is 67108865 bytes, more than the 64 MiB accepted for a JSON file")) << message;
}

TEST(InputFile, AJsonFileAtItsLimitIsReadAndJudgedOnItsContent) {
  TempDir dir;
  const auto file = sparse_file(dir.path / "at-limit.json", evar::base::kJsonLimit.bytes);
  const std::string message = error_of([&] { detail::parse_json_file(file); });
  EXPECT_THAT(message, HasSubstr("at-limit.json: invalid JSON")) << message;
}

TEST(InputFile, MeshAndDicomFilesHaveTheirOwnLimits) {
  TempDir dir;
  const auto mesh = sparse_file(dir.path / "vessel.stl", evar::base::kMeshLimit.bytes + 4096);
  EXPECT_THAT(error_of([&] { read_mesh(mesh); }), HasSubstr("vessel.stl: is 1073745920 bytes, more than the 1024 MiB accepted for a mesh file"));
  const auto dicom = sparse_file(dir.path / "run.dcm", evar::base::kDicomLimit.bytes + 1);
  EXPECT_THAT(error_of([&] { read_xa_dicom(dicom); }), HasSubstr("run.dcm: is 4294967297 bytes, more than the 4096 MiB accepted for a DICOM file"));
  // A mesh of the JSON limit's size is still a mesh the mesh limit accepts: the limits are per kind.
  evar::base::check_input_file(sparse_file(dir.path / "big.stl", evar::base::kJsonLimit.bytes + 1), evar::base::kMeshLimit);
}

TEST(InputFile, AFifoOrADirectoryIsRefusedWithoutBlocking) {
  TempDir dir;
  const fs::path fifo = dir.path / "scene.json";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_THAT(error_of([&] { detail::parse_json_file(fifo); }), HasSubstr("scene.json: is not a regular file"));
  fs::create_directory(dir.path / "aorta.stl");
  EXPECT_THAT(error_of([&] { read_mesh(dir.path / "aorta.stl"); }), HasSubstr("aorta.stl: is a directory, not a file"));
  EXPECT_THAT(error_of([&] { evar::base::read_input_file(dir.path / "absent.csv", evar::base::kTableLimit); }), HasSubstr("absent.csv: file does not exist"));
}

TEST(InputFile, ReadsTheWholeFileWithinTheLimit) {
  TempDir dir;
  std::string bytes(200'000, 'x');
  bytes[123'456] = '\0';  // binary-safe
  std::ofstream(dir.path / "t.csv", std::ios::binary) << bytes;
  EXPECT_EQ(evar::base::read_input_file(dir.path / "t.csv", evar::base::kTableLimit), bytes);
  EXPECT_THAT(error_of([&] { evar::base::read_input_file(dir.path / "t.csv", evar::base::InputLimit{100'000, "a test file"}); }),
              HasSubstr("t.csv: is 200000 bytes, more than the 100000 bytes accepted for a test file"));
}

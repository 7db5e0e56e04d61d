// Files written whole or not at all: the target holds either its old bytes or all the new
// ones, a failure names the file and why, and no partial file is left behind.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <cstdlib>
#include <string>
#include <system_error>

#include "evar/base/atomic_file.hpp"
#include "support/temp_dir.hpp"

namespace fs = std::filesystem;
using evar::base::AtomicFile;
using evar::base::Durability;
using evar::base::write_file_atomically;

namespace {

std::string contents(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

std::size_t entries(const fs::path& dir) {
  return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir), fs::directory_iterator{}));
}

}  // namespace

TEST(AtomicFile, ReplacesTheTargetWithAllTheBytesAndLeavesNothingElse) {
  const evar::test::TempDir dir;
  const fs::path target = dir.path / "report.json";
  write_file_atomically(target, "old\n");
  // More than the writer's buffer, in pieces of every size, so flushing mid-way is exercised.
  std::string expected;
  AtomicFile file(target);
  for (int i = 0; i < 3000; ++i) {
    const std::string piece(static_cast<std::size_t>(i % 97) + (i == 1500 ? 200000 : 0), static_cast<char>('a' + i % 26));
    file.write(piece);
    expected += piece;
  }
  EXPECT_EQ(contents(target), "old\n");  // not committed yet: readers still see the old file
  EXPECT_EQ(entries(dir.path), 2u);      // the target and its partial file
  file.commit();
  EXPECT_EQ(contents(target), expected);
  EXPECT_EQ(entries(dir.path), 1u);
}

TEST(AtomicFile, NotCommittedLeavesTheOldFileAndRemovesThePartialOne) {
  const evar::test::TempDir dir;
  const fs::path target = dir.path / "mesh.stl";
  write_file_atomically(target, "whole", Durability::Deferred);
  {
    AtomicFile file(target);
    file.write("half of a new mesh");
  }  // an exception on the way out of a writer ends here
  EXPECT_EQ(contents(target), "whole");
  EXPECT_EQ(entries(dir.path), 1u);
}

TEST(AtomicFile, TheWrittenFileIsAsReadableAsAnyTheUserCreates) {
  const evar::test::TempDir dir;
  const fs::path target = dir.path / "picture.png";
  const mode_t old = ::umask(022);
  write_file_atomically(target, "png");
  ::umask(old);
  EXPECT_EQ(fs::status(target).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::others_read);
}

// /dev/full answers every write with ENOSPC: the error names the file and says why, and a
// device, which cannot be replaced, is written in place and never removed.
TEST(AtomicFile, AFullDiskIsSaidByNameAndADeviceIsWrittenInPlace) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full here";
  try {
    write_file_atomically("/dev/full", std::string(100000, 'x'));
    ADD_FAILURE() << "a write to a full disk succeeded";
  } catch (const std::system_error& e) {
    EXPECT_EQ(e.code().value(), ENOSPC);
    EXPECT_NE(std::string(e.what()).find("/dev/full: cannot write"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("disk full?"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::is_character_file("/dev/full"));
  write_file_atomically("/dev/null", "gone");  // a device that accepts writes
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
}

TEST(AtomicFile, AFolderThatDoesNotExistIsNamedInTheError) {
  const evar::test::TempDir dir;
  const fs::path target = dir.path / "no" / "such" / "folder" / "out.json";
  try {
    write_file_atomically(target, "{}");
    ADD_FAILURE() << "wrote into a missing folder";
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find(target.string() + ": cannot create"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("No such file or directory"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir.path / "no"));
}

TEST(AtomicFile, NothingIsWrittenAfterCommit) {
  const evar::test::TempDir dir;
  AtomicFile file(dir.path / "a.txt");
  file.write("a");
  file.commit();
  EXPECT_THROW(file.write("b"), std::logic_error);
  EXPECT_THROW(file.commit(), std::logic_error);
  EXPECT_EQ(contents(dir.path / "a.txt"), "a");
}

TEST(AtomicFile, AReplacedFileKeepsItsPermissions) {
  const evar::test::TempDir dir;
  const fs::path target = dir.path / "report.json";
  write_file_atomically(target, "old");
  fs::permissions(target, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  write_file_atomically(target, "new");
  EXPECT_EQ(contents(target), "new");
  EXPECT_EQ(fs::status(target).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
}

// A symbolic link is written through, as a plain write would: the link stays a link.
TEST(AtomicFile, ASymbolicLinkIsWrittenThroughAndStaysALink) {
  const evar::test::TempDir dir;
  fs::create_directories(dir.path / "elsewhere");
  write_file_atomically(dir.path / "elsewhere" / "mesh.stl", "old");
  fs::create_symlink(dir.path / "elsewhere" / "mesh.stl", dir.path / "mesh.stl");
  write_file_atomically(dir.path / "mesh.stl", "new");
  EXPECT_TRUE(fs::is_symlink(dir.path / "mesh.stl"));
  EXPECT_EQ(contents(dir.path / "elsewhere" / "mesh.stl"), "new");
  EXPECT_EQ(entries(dir.path), 2u);
}

// An existing file in a folder we may not add to is still written (in place); a file we
// may not write is not replaced. Root may write anything, so there the checks run in a
// child that has become nobody.
TEST(AtomicFile, PermissionsAreThoseOfAPlainWrite) {
  const evar::test::TempDir dir;
  const fs::path locked = dir.path / "locked";
  fs::create_directories(locked);
  write_file_atomically(locked / "a.json", "old");
  const auto checks = [&]() -> int {
    if (::geteuid() == 0) {
      constexpr uid_t kNobody = 65534;
      // The scratch root above the test's folder is the process's own: nobody may pass it.
      fs::permissions(dir.path.parent_path(), fs::perms::others_exec, fs::perm_options::add);
      if (::chown(dir.path.c_str(), kNobody, kNobody) != 0 || ::chown(locked.c_str(), kNobody, kNobody) != 0 ||
          ::chown((locked / "a.json").c_str(), kNobody, kNobody) != 0 || ::setgid(kNobody) != 0 || ::setuid(kNobody) != 0)
        return 10;
    }
    fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec);
    write_file_atomically(locked / "a.json", "new");  // in place
    if (contents(locked / "a.json") != "new") return 11;
    try {
      write_file_atomically(locked / "b.json", "x");  // a new file needs the folder
      return 12;
    } catch (const std::system_error&) {
    }
    fs::permissions(locked, fs::perms::owner_all);
    fs::permissions(locked / "a.json", fs::perms::owner_read);
    try {
      write_file_atomically(locked / "a.json", "newer");
      return 13;
    } catch (const std::system_error& e) {
      if (std::string(e.what()).find("a.json: cannot write") == std::string::npos) return 14;
    }
    if (contents(locked / "a.json") != "new") return 15;
    return entries(locked) == 1 ? 0 : 16;
  };
  EXPECT_EXIT(std::exit(checks()), testing::ExitedWithCode(0), "");
}

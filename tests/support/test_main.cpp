// The test programs' main: every test process works in a scratch root of its own, removed
// when the process ends, so a run of the suite leaves nothing behind in /tmp and parallel
// processes never meet. Both ways tests ask for a temporary directory read the root from
// the environment: std::filesystem::temp_directory_path() (TMPDIR) and
// testing::TempDir() (TEST_TMPDIR). Child processes the tests start inherit it.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>

int main(int argc, char** argv) {
  const char* parent = std::getenv("TMPDIR");
  std::string root = std::string(parent && *parent ? parent : "/tmp") + "/evar-test-XXXXXX";
  if (::mkdtemp(root.data()) == nullptr) {
    std::perror(("test main: cannot make a scratch root under " + root).c_str());
    return 2;
  }
  ::setenv("TMPDIR", root.c_str(), 1);
  ::setenv("TEST_TMPDIR", (root + "/").c_str(), 1);

  testing::InitGoogleTest(&argc, argv);
  const int result = RUN_ALL_TESTS();

  std::error_code ignored;  // what a test could not remove is not a test failure
  std::filesystem::remove_all(root, ignored);
  return result;
}

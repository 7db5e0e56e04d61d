#pragma once
// A fresh directory for the running test, named after it and the process (so parallel
// test processes never share one), removed with everything in it at the end of its scope.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace evar::test {

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    const auto* test = testing::UnitTest::GetInstance()->current_test_info();
    path = std::filesystem::temp_directory_path() /
           ("evar_" + std::string(test ? test->test_suite_name() : "test") + "_" +
            std::string(test ? test->name() : "") + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TempDir() {
    std::error_code ignored;  // a destructor must not throw
    std::filesystem::remove_all(path, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

}  // namespace evar::test

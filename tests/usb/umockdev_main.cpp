// The USB test program's main: libusb must see umockdev's sysfs and /dev, so the program
// re-executes itself under umockdev's preload library (as umockdev-wrapper does).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

int main(int argc, char** argv) {
  // libusb must see umockdev's sysfs and /dev: run under its preload library.
  const char* old = std::getenv("LD_PRELOAD");
  if (!old || !std::strstr(old, "libumockdev-preload")) {
    std::string preload = "libumockdev-preload.so.0";
    if (old && *old) preload = std::string(old) + ":" + preload;
    ::setenv("LD_PRELOAD", preload.c_str(), 1);
    ::setenv("ASAN_OPTIONS", (std::string(std::getenv("ASAN_OPTIONS") ? std::getenv("ASAN_OPTIONS") : "") + ":verify_asan_link_order=0").c_str(), 1);
    ::execv("/proc/self/exe", argv);
    std::perror("re-executing under umockdev's preload library");
    return 1;
  }
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}

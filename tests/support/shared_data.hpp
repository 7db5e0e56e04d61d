#pragma once
// The third-party test data beside the project (../shared/data, see its README): real
// material the project did not make. A user's checkout does not have it, so a test that
// uses it skips, saying so, when it is absent. EVAR_SHARED_DATA overrides the location.
#include <cstdlib>
#include <filesystem>
#include <optional>

namespace evar::test {

/// ../shared/data/vmtk-aorta (VMTK's aorto-iliac test data), or nullopt when absent.
inline std::optional<std::filesystem::path> vmtk_aorta_dir() {
  const char* env = std::getenv("EVAR_SHARED_DATA");
  const std::filesystem::path root =
      env && *env ? std::filesystem::path(env) : std::filesystem::path(EVAR_SOURCE_DIR) / ".." / "shared" / "data";
  const auto dir = root / "vmtk-aorta";
  if (!std::filesystem::exists(dir / "aorta-surface.vtp")) return std::nullopt;
  return dir;
}

}  // namespace evar::test

/// Skips the test, saying why, when the VMTK data is absent; else binds `dir` to it.
#define EVAR_VMTK_DATA_OR_SKIP(dir)                                                                     \
  const auto dir##_found = evar::test::vmtk_aorta_dir();                                                \
  if (!dir##_found)                                                                                     \
    GTEST_SKIP() << "third-party data ../shared/data/vmtk-aorta is absent (a user's checkout has none; " \
                    "set EVAR_SHARED_DATA to its parent folder to run this test)";                      \
  const std::filesystem::path dir = *dir##_found

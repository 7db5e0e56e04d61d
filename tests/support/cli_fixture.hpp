#pragma once
// The command-line tests' fixture: `evarnode` run in process with its exit code and what it
// said, and a small example scene written once per test process.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "evar/app/cli.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/sim/example_scene.hpp"

namespace evar::test {

namespace fs = std::filesystem;

struct Run {
  int code;
  std::string err;
};

inline Run evarnode(const std::vector<std::string>& args) {
  testing::internal::CaptureStderr();
  testing::internal::CaptureStdout();
  const int code = evar::app::run_cli(args);
  testing::internal::GetCapturedStdout();
  return {code, testing::internal::GetCapturedStderr()};
}

inline void write_text(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

// A small example scene, written once for the whole suite.
class Cli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // Per process: ctest runs each test in its own process, in parallel.
    dir_ = fs::path(testing::TempDir()) / ("evar_cli_example_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    evar::sim::ExampleSceneParams p;
    p.aorta_vertices = 2500;
    p.iliac_vertices = 1500;
    evar::sim::write_example_scene(evar::sim::make_example_scene(p), dir_);
  }
  static inline fs::path dir_;
  fs::path scene() const { return dir_ / "scene.json"; }
  fs::path device() const { return dir_ / "device.mrk.json"; }
  fs::path scratch(const std::string& name) const {
    const auto p = fs::path(testing::TempDir()) / ("evar_cli_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
  }
  void expect_deform_keeps(evar::geometry::MeshFormat format, const std::string& extension);
  std::string curve_json(const std::string& points) const {
    return R"({"markups": [{"type": "Curve", "coordinateSystem": "LPS", "controlPoints": [)" + points + "]}]}";
  }
};

}  // namespace evar::test

#pragma once
// The subcommands, each parsed by cli.cpp into its options struct.
#include <filesystem>
#include <optional>
#include <string>

namespace evar::app {

struct DeformCommand {
  std::filesystem::path scene, device, out;
  bool skeleton = true;
  bool preview = true;
  std::string solver = "default";
  double tolerance_mm = 0.01;
  int max_iterations = 500;
  int containment_rounds = 3;
  double tether_mm = 50.0;
};
int run_deform(const DeformCommand& cmd);

struct ArapCommand {
  std::filesystem::path mesh, constraints, out, report;
  std::optional<int> iterations;
  std::optional<double> tolerance_mm;
  std::string solver = "default";
  bool anderson = true;
};
int run_arap(const ArapCommand& cmd);

struct ExampleCommand {
  std::filesystem::path out;
  std::string format = "stl";
  unsigned long long seed = 1;
  int aorta_vertices = 7500;
  int iliac_vertices = 3500;
};
int run_example(const ExampleCommand& cmd);

struct ProjectCommand {
  std::filesystem::path geometry, registration, points, out;
};
int run_project(const ProjectCommand& cmd);

}  // namespace evar::app

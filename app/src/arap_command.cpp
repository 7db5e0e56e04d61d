// `evarnode arap`: plain surface ARAP for explicit constraints.
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "evar/deform/arap_solver.hpp"
#include "evar/deform/cotangent_weights.hpp"
#include "evar/base/input_error.hpp"
#include "evar/geometry/json_fields.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/node/logging.hpp"
#include "json_file.hpp"

namespace evar::app {
namespace {

struct Constraints {
  std::vector<int> vertices;
  geometry::Vertices targets;
};

// Reads {"fixed": [i...], "handles": [{"vertex": i, "target": [x, y, z]}]}; every error
// names the file and the JSON path. Targets are in the mesh file's coordinates: RAS where
// the file says SPACE=RAS (`V` is LPS, as read_mesh gives it), turned into LPS here.
Constraints read_constraints(const std::filesystem::path& path, const geometry::Vertices& V, geometry::MeshSpace space) {
  using base::InputError;
  const std::string file = path.string();
  const nlohmann::json j = geometry::detail::parse_json_file(path);
  if (!j.is_object()) throw base::InputError(file + ": the top level must be an object with \"fixed\" and/or \"handles\"");
  for (const auto& [key, value] : j.items())
    if (key != "fixed" && key != "handles")
      throw base::InputError(file + ": unknown key \"" + key + "\" (expected \"fixed\" and/or \"handles\")");
  const auto n = static_cast<long long>(V.rows());
  std::vector<int> owner(static_cast<std::size_t>(n), -1);
  Constraints c;
  std::vector<Eigen::RowVector3d> rows;
  auto add = [&](long long v, const Eigen::RowVector3d& target, const std::string& where) {
    if (v < 0 || v >= n)
      throw base::InputError(file + ": " + where + ": vertex " + std::to_string(v) + " is out of range (the mesh has " +
                       std::to_string(n) + " vertices)");
    if (owner[static_cast<std::size_t>(v)] >= 0)
      throw base::InputError(file + ": " + where + ": vertex " + std::to_string(v) + " is constrained twice");
    owner[static_cast<std::size_t>(v)] = static_cast<int>(rows.size());
    c.vertices.push_back(static_cast<int>(v));
    rows.push_back(target);
  };
  if (j.contains("fixed")) {
    if (!j["fixed"].is_array()) throw base::InputError(file + ": fixed: must be an array of vertex indices");
    for (std::size_t k = 0; k < j["fixed"].size(); ++k) {
      const auto& e = j["fixed"][k];
      const std::string where = "fixed[" + std::to_string(k) + "]";
      if (!e.is_number_integer() || (e.is_number_unsigned() && e.get<unsigned long long>() > 0x7fffffffULL))
        throw base::InputError(file + ": " + where + ": must be an integer vertex index");
      const long long v = e.get<long long>();
      if (v < 0 || v >= n) add(v, Eigen::RowVector3d::Zero(), where);  // throws the range message
      add(v, V.row(v), where);
    }
  }
  if (j.contains("handles")) {
    if (!j["handles"].is_array()) throw base::InputError(file + ": handles: must be an array");
    for (std::size_t k = 0; k < j["handles"].size(); ++k) {
      const auto& h = j["handles"][k];
      const std::string where = "handles[" + std::to_string(k) + "]";
      if (!h.is_object() || !h.contains("vertex") || !h["vertex"].is_number_integer() ||
          (h["vertex"].is_number_unsigned() && h["vertex"].get<unsigned long long>() > 0x7fffffffULL))
        throw base::InputError(file + ": " + where + ".vertex: must be an integer vertex index");
      if (!h.contains("target") || !h["target"].is_array() || h["target"].size() != 3)
        throw base::InputError(file + ": " + where + ".target: must be [x, y, z] in mm");
      Eigen::RowVector3d t;
      for (int a = 0; a < 3; ++a) {
        const auto& x = h["target"][static_cast<std::size_t>(a)];
        if (!x.is_number() || !std::isfinite(x.get<double>()))
          throw base::InputError(file + ": " + where + ".target[" + std::to_string(a) + "]: must be a finite number");
        t[a] = x.get<double>();
      }
      if (space == geometry::MeshSpace::Ras) t.head<2>() = -t.head<2>();
      add(h["vertex"].get<long long>(), t, where);
    }
  }
  if (c.vertices.empty()) throw base::InputError(file + ": no constraints: give at least one fixed or handle vertex");
  c.targets.resize(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t k = 0; k < rows.size(); ++k) c.targets.row(static_cast<Eigen::Index>(k)) = rows[k];
  return c;
}

}  // namespace

int run_arap(const ArapCommand& cmd) {
  const auto loaded = geometry::read_mesh(cmd.mesh);
  geometry::validate_mesh(loaded.mesh, cmd.mesh.string());
  const auto& mesh = loaded.mesh;
  const auto constraints = read_constraints(cmd.constraints, mesh.V, loaded.space);
  node::log().info("{}: {} vertices, {} faces; {} constrained vertices", cmd.mesh.string(), mesh.V.rows(), mesh.F.rows(),
             constraints.vertices.size());

  deform::ArapOptions opt;
  opt.backend = deform::parse_cholesky_backend(cmd.solver);
  opt.anderson = cmd.anderson;
  if (cmd.iterations) {
    opt.max_iterations = *cmd.iterations;
    opt.tolerance_mm = std::numeric_limits<double>::min();  // run them all
  } else if (cmd.tolerance_mm) {
    opt.tolerance_mm = *cmd.tolerance_mm;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const auto edges = deform::cotangent_weights(mesh);
  const double weights_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  deform::ArapSolver solver = [&] {
    try {
      return deform::ArapSolver(deform::mesh_arap_terms(mesh.V, edges), constraints.vertices, opt);
    } catch (const std::invalid_argument& e) {
      throw base::InputError(cmd.constraints.string() + ": " + e.what());
    }
  }();
  const auto r = solver.solve(constraints.targets);
  if (!r.X.allFinite() || !std::isfinite(r.energy.back()))
    throw std::runtime_error(cmd.mesh.string() + ": the ARAP solve produced non-finite positions (coordinates or targets out of range?); nothing written");
  geometry::TriangleMesh out{r.X, mesh.F};
  geometry::write_mesh(cmd.out, out, geometry::format_for_extension(cmd.out), loaded.space);
  const double per_iteration = r.iterations > 0 ? r.iterate_ms / r.iterations : 0.0;
  node::log().info("factor {:.2f} ms ({}), {} iterations in {:.2f} ms ({:.3f} ms each), energy {:.6g}{}; wrote {}",
             solver.factor_ms(), deform::to_string(solver.backend()), r.iterations, r.iterate_ms, per_iteration,
             r.energy.back(), r.converged || cmd.iterations ? "" : " (iteration cap reached)", cmd.out.string());
  if (!cmd.report.empty()) {
    nlohmann::json j = {{"format", "evarnode-arap-report"},
                        {"version", 1},
                        {"mesh", cmd.mesh.string()},
                        {"vertices", mesh.V.rows()},
                        {"faces", mesh.F.rows()},
                        {"constrained_vertices", constraints.vertices.size()},
                        {"solver", deform::to_string(solver.backend())},
                        {"anderson", cmd.anderson},
                        {"weights_ms", weights_ms},
                        {"assemble_ms", solver.assemble_ms()},
                        {"factor_ms", solver.factor_ms()},
                        {"init_ms", r.init_ms},
                        {"iterations", r.iterations},
                        {"iterate_ms", r.iterate_ms},
                        {"per_iteration_ms", per_iteration},
                        {"converged", r.converged},
                        {"last_update_mm", r.last_update_mm},
                        {"energy", r.energy.back()},
                        {"energy_history", r.energy}};
    write_json(cmd.report, j);
  }
  return 0;
}

}  // namespace evar::app

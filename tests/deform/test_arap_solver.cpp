#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/OrderingMethods>
#include <algorithm>
#include <vector>

#include "evar/deform/arap_solver.hpp"
#include "evar/deform/registration_tether.hpp"
#include "support/energy_descent.hpp"
#include "tube_fixture.hpp"

using namespace evar;
using deform::ArapOptions;
using deform::ArapSolver;
using geometry::Vertices;

namespace {
geometry::Vertices rows_of(const geometry::Vertices& X, const std::vector<int>& idx) {
  geometry::Vertices out(static_cast<Eigen::Index>(idx.size()), 3);
  for (std::size_t k = 0; k < idx.size(); ++k) out.row(static_cast<Eigen::Index>(k)) = X.row(idx[k]);
  return out;
}
geometry::Vertices rigid(const geometry::Vertices& X, const Eigen::Matrix3d& Q, const Eigen::Vector3d& t) {
  return ((X * Q.transpose()).rowwise() + t.transpose()).eval();
}
}  // namespace

TEST(ArapSolver, NoDisplacementGivesTheInputBack) {
  const auto m = test::straight_tube();
  const auto fixed = test::vertices_outside_z(m, 1.0, 59.0);
  const ArapSolver solver(test::tube_terms(m), fixed);
  const auto r = solver.solve(rows_of(m.V, fixed));
  EXPECT_TRUE(r.converged);
  EXPECT_LT((r.X - m.V).cwiseAbs().maxCoeff(), 1e-9);
  // The energy is evaluated as Σw|e'|² + Σw|e|² − 2 tr(RᵀS): terms of ~1e4 mm² cancel,
  // so double rounding leaves ~1e-9 mm²; 1e-6 mm² is still far below any real strain.
  EXPECT_LT(r.energy.back(), 1e-6);
}

TEST(ArapSolver, RigidMotionOfAllHandlesGivesThatRigidMotion) {
  const auto m = test::straight_tube();
  const auto handles = test::vertices_outside_z(m, 3.0, 57.0);
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(0.6, Eigen::Vector3d(1, 2, 0.5).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(12.0, -4.0, 30.0);
  ArapOptions opt;
  opt.tolerance_mm = 1e-9;
  opt.max_iterations = 5000;
  const ArapSolver solver(test::tube_terms(m), handles, opt);
  const auto r = solver.solve(rows_of(rigid(m.V, Q, t), handles));
  ASSERT_TRUE(r.converged);
  // Tolerance: the stopping rule (1e-9 mm update) bounds the distance to the exact
  // solution well below a micrometre.
  EXPECT_LT((r.X - rigid(m.V, Q, t)).rowwise().norm().maxCoeff(), 1e-6);
}

TEST(ArapSolver, HandlesReachTheirTargetsExactly) {
  const auto m = test::straight_tube();
  const auto fixed = test::vertices_outside_z(m, 1.0, 1e9);  // bottom ring + cap
  std::vector<int> handles = fixed;
  geometry::Vertices targets = rows_of(m.V, fixed);
  // Pull the top ring 10 mm sideways.
  for (Eigen::Index i = 0; i < m.V.rows(); ++i)
    if (m.V(i, 2) > 59.0) {
      handles.push_back(static_cast<int>(i));
      targets.conservativeResize(targets.rows() + 1, 3);
      targets.row(targets.rows() - 1) = m.V.row(i) + Eigen::RowVector3d(10, 0, 0);
    }
  const ArapSolver solver(test::tube_terms(m), handles);
  const auto r = solver.solve(targets);
  EXPECT_LT((rows_of(r.X, handles) - targets).cwiseAbs().maxCoeff(), 1e-12);
}

class ArapEnergy : public ::testing::TestWithParam<bool> {};

TEST_P(ArapEnergy, NeverIncreasesAcrossIterations) {
  const auto m = test::straight_tube();
  std::vector<int> handles;
  std::vector<Eigen::RowVector3d> target_list;
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
    if (m.V(i, 2) < 1.0) {
      handles.push_back(static_cast<int>(i));
      target_list.push_back(m.V.row(i));
    } else if (m.V(i, 2) > 59.0) {  // top ring bent by ~70 degrees
      handles.push_back(static_cast<int>(i));
      target_list.push_back((Q * m.V.row(i).transpose() + Eigen::Vector3d(0, -20, -15)).transpose());
    }
  }
  geometry::Vertices targets(static_cast<Eigen::Index>(target_list.size()), 3);
  for (std::size_t k = 0; k < target_list.size(); ++k) targets.row(static_cast<Eigen::Index>(k)) = target_list[k];
  ArapOptions opt;
  opt.anderson = GetParam();
  opt.max_iterations = 300;
  opt.tolerance_mm = 1e-4;
  const ArapSolver solver(test::tube_terms(m), handles, opt);
  const auto r = solver.solve(targets);
  ASSERT_GE(r.energy.size(), 3u);
  EXPECT_TRUE(evar::test::energy_never_rises(r.energy));
  EXPECT_LT(r.energy.back(), 0.9 * r.energy.front());  // the iterations did real work
}
INSTANTIATE_TEST_SUITE_P(PlainAndAnderson, ArapEnergy, ::testing::Values(false, true));

TEST(ArapSolver, AndersonReachesTheSameFixedPointInFewerIterations) {
  const auto m = test::straight_tube();
  std::vector<int> handles;
  geometry::Vertices targets(0, 3);
  for (Eigen::Index i = 0; i < m.V.rows(); ++i)
    if (m.V(i, 2) < 1.0 || m.V(i, 2) > 59.0) {
      handles.push_back(static_cast<int>(i));
      targets.conservativeResize(targets.rows() + 1, 3);
      const double z = m.V(i, 2);
      targets.row(targets.rows() - 1) = m.V.row(i) + Eigen::RowVector3d(z > 30 ? 25.0 : 0.0, 0, z > 30 ? -10.0 : 0.0);
    }
  ArapOptions plain, fast;
  plain.anderson = false;
  plain.tolerance_mm = fast.tolerance_mm = 1e-5;
  plain.max_iterations = fast.max_iterations = 20000;
  const auto rp = ArapSolver(test::tube_terms(m), handles, plain).solve(targets);
  const auto ra = ArapSolver(test::tube_terms(m), handles, fast).solve(targets);
  ASSERT_TRUE(rp.converged);
  ASSERT_TRUE(ra.converged);
  EXPECT_LT((rp.X - ra.X).rowwise().norm().maxCoeff(), 0.05);
  EXPECT_LT(ra.iterations, rp.iterations / 2);
}

TEST(ArapSolver, RefusesAPartWithoutAnyConstraint) {
  auto a = test::straight_tube(20.0);
  auto b = test::straight_tube(20.0);
  geometry::TriangleMesh both;
  both.V.resize(a.V.rows() * 2, 3);
  both.V << a.V, (b.V.rowwise() + Eigen::RowVector3d(50, 0, 0));
  both.F.resize(a.F.rows() * 2, 3);
  both.F << a.F, (b.F.array() + static_cast<int>(a.V.rows())).matrix();
  try {
    ArapSolver solver(test::tube_terms(both), {0});
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no fixed or handle vertex"), std::string::npos) << e.what();
  }
}

TEST(ArapSolver, WarmStartFromTheSolutionConvergesImmediately) {
  const auto m = test::straight_tube();
  const auto handles = test::vertices_outside_z(m, 1.0, 59.0);
  geometry::Vertices targets = rows_of(m.V, handles);
  for (Eigen::Index k = 0; k < targets.rows(); ++k)
    if (targets(k, 2) > 30) targets(k, 0) += 8.0;
  const ArapSolver solver(test::tube_terms(m), handles);
  const auto cold = solver.solve(targets);
  const auto warm = solver.solve(targets, &cold.X);
  EXPECT_LE(warm.iterations, 2);
  EXPECT_LT((warm.X - cold.X).rowwise().norm().maxCoeff(), 0.05);
}

namespace {
// A tethered tube with a few handles pulled sideways, as the aorta is in a scene.
struct TetheredPull {
  geometry::TriangleMesh mesh = test::straight_tube();
  std::shared_ptr<const deform::ArapSystem> system;
  std::vector<int> handles;
  geometry::Vertices targets;
  explicit TetheredPull(int count) {
    ArapOptions opt;
    opt.tolerance_mm = 1e-7;
    system = std::make_shared<const deform::ArapSystem>(test::tube_terms(mesh), opt,
                                                        deform::registration_tether(mesh, static_cast<int>(mesh.V.rows()), 50.0));
    for (Eigen::Index i = 0; i < mesh.V.rows() && static_cast<int>(handles.size()) < count; i += 7)
      if (mesh.V(i, 2) > 20.0 && mesh.V(i, 2) < 40.0 && mesh.V(i, 0) > 0.0) handles.push_back(static_cast<int>(i));
    targets = rows_of(mesh.V, handles);
    targets.col(0).array() += 3.0;
  }
};
}  // namespace

TEST(ArapSolver, CapacitanceAndRefactorGiveTheSameDeformation) {
  const TetheredPull pull(12);
  ASSERT_EQ(pull.handles.size(), 12u);
  ASSERT_NE(pull.system->prefactored(), nullptr);
  const ArapSolver refactor(pull.system, pull.handles, deform::ConstraintMethod::Refactor);
  const ArapSolver capacitance(pull.system, pull.handles, deform::ConstraintMethod::Capacitance);
  ASSERT_EQ(capacitance.method(), deform::ConstraintMethod::Capacitance);
  const auto a = refactor.solve(pull.targets);
  const auto b = capacitance.solve(pull.targets);
  ASSERT_TRUE(a.converged && b.converged);
  // Both solve the same global step to rounding; a 1e-7 mm stopping rule leaves both
  // within micrometres of the one fixed point.
  EXPECT_LT((a.X - b.X).rowwise().norm().maxCoeff(), 1e-5);
  EXPECT_LT((rows_of(b.X, pull.handles) - pull.targets).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_GT((b.X - pull.mesh.V).rowwise().norm().maxCoeff(), 2.9);  // it did move
}

TEST(ArapSolver, AutomaticMethodFollowsTheOperationCount) {
  const TetheredPull few(4);
  EXPECT_EQ(ArapSolver(few.system, few.handles).method(), deform::ConstraintMethod::Capacitance);
  // Every vertex of the tube's lower half: forming A⁻¹E would cost far more than a factor.
  const auto many = test::vertices_outside_z(few.mesh, 30.0, 1e9);
  EXPECT_EQ(ArapSolver(few.system, many).method(), deform::ConstraintMethod::Refactor);
}

TEST(ArapSolver, CapacitanceNeedsATether) {
  const auto m = test::straight_tube();
  auto system = std::make_shared<const deform::ArapSystem>(test::tube_terms(m));
  EXPECT_EQ(system->prefactored(), nullptr);
  EXPECT_THROW(ArapSolver(system, test::vertices_outside_z(m, 1.0, 59.0), deform::ConstraintMethod::Capacitance),
               std::invalid_argument);
}

TEST(ArapSolver, ALargeMeshIsOrderedByNestedDissectionWithLessFillAndSolvesTheSame) {
  // 600 mm of tube, 48 around every 1 mm: about 29k vertices, past the size from which the
  // ordering is METIS nested dissection (sparse_cholesky.hpp).
  const auto m = test::straight_tube(600.0, 8.0, 48, 1.0);
  ASSERT_GE(m.V.rows(), deform::kNestedDissectionFromUnknowns);
  const auto terms = test::tube_terms(m);
  Eigen::SparseMatrix<double> A = deform::assemble_system_matrix(terms);
  Eigen::SparseMatrix<double> I(A.rows(), A.cols());
  I.setIdentity();
  A += 1e-3 * I;  // a tether makes A positive definite on its own
  const auto ordering = deform::fill_reducing_ordering(A);
  ASSERT_EQ(ordering.size(), A.rows());
  std::vector<int> seen(static_cast<std::size_t>(A.rows()), 0);
  for (Eigen::Index i = 0; i < ordering.size(); ++i) ++seen[static_cast<std::size_t>(ordering.indices()[i])];
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), A.rows());  // a permutation
  if (deform::nested_dissection_available()) {
    // Against AMD on the same pattern: measured 25-40 % fewer entries in L on vessel meshes
    // of 30k-120k vertices; a straight tube is the easy case for AMD, so only "fewer".
    Eigen::SparseMatrix<double> full;
    full = A.selfadjointView<Eigen::Lower>();
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> amd;
    Eigen::AMDOrdering<int>()(full, amd);
    const deform::SparseCholesky with_nd(A, ordering, deform::CholeskyBackend::EigenLDLT);
    const deform::SparseCholesky with_amd(A, amd, deform::CholeskyBackend::EigenLDLT);
    EXPECT_LT(with_nd.factor_nonzeros(), with_amd.factor_nonzeros());
  }
  // And the solver built on it does what it does on small meshes: all handles moved
  // rigidly give that rigid motion everywhere.
  const auto handles = test::vertices_outside_z(m, 3.0, 597.0);
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.3, 1, 0.2).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(4, -2, 7);
  ArapOptions opt;
  opt.tolerance_mm = 1e-7;
  const ArapSolver solver(terms, handles, opt);
  const auto r = solver.solve(rows_of(rigid(m.V, Q, t), handles));
  ASSERT_TRUE(r.converged);
  EXPECT_LT((r.X - rigid(m.V, Q, t)).rowwise().norm().maxCoeff(), 1e-4);
}

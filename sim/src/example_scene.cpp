#include "evar/sim/example_scene.hpp"

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/sim/tube_mesh.hpp"
#include "seeded_uniform.hpp"

namespace evar::sim {
namespace {

using geometry::Polyline;
constexpr double kPi = std::numbers::pi;
constexpr double kCenterlineStepMm = 1.0;
constexpr int kDenseSamples = 4000;  // parametric samples before arc-length resampling

// Uniform perturbations in [-amplitude, amplitude) * scale.
class Perturbation {
 public:
  Perturbation(std::uint64_t seed, double scale) : uniform_(seed), scale_(scale) {}
  double operator()(double amplitude) { return (2.0 * uniform_.unit() - 1.0) * amplitude * scale_; }

 private:
  SeededUniform uniform_;
  double scale_;
};

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("make_example_scene: ") + what);
}

double mean_radius(const Polyline& centerline, const std::vector<double>& radii) {
  const auto arc = geometry::arc_lengths(centerline);
  double integral = 0.0;
  for (std::size_t i = 1; i < arc.size(); ++i) integral += 0.5 * (radii[i - 1] + radii[i]) * (arc[i] - arc[i - 1]);
  return integral / arc.back();
}

// A curve given by a parametric function on [0, 1], resampled every 1 mm of arc length
// with both ends kept exactly.
template <class Curve>
Polyline sample_curve(const Curve& curve) {
  Polyline dense;
  dense.reserve(kDenseSamples + 1);
  for (int i = 0; i <= kDenseSamples; ++i) dense.push_back(curve(static_cast<double>(i) / kDenseSamples));
  Polyline out = geometry::resample(dense, kCenterlineStepMm);
  out.back() = dense.back();
  return out;
}

// Nearest intersection (t > 0) of the ray origin + t dir with the mesh, returned as the
// barycentric combination of its triangle's corners so that it lies on the surface to
// rounding (Moeller-Trumbore in double).
std::optional<Eigen::Vector3d> first_hit(const geometry::TriangleMesh& mesh, const Eigen::Vector3d& origin,
                                         const Eigen::Vector3d& dir) {
  double best_t = std::numeric_limits<double>::infinity();
  std::optional<Eigen::Vector3d> best;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose();
    const Eigen::Vector3d b = mesh.V.row(mesh.F(f, 1)).transpose();
    const Eigen::Vector3d c = mesh.V.row(mesh.F(f, 2)).transpose();
    const Eigen::Vector3d e1 = b - a, e2 = c - a;
    const Eigen::Vector3d p = dir.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-14) continue;  // ray parallel to the triangle
    const Eigen::Vector3d q = origin - a;
    const double u = q.dot(p) / det;
    if (u < 0.0 || u > 1.0) continue;
    const Eigen::Vector3d r = q.cross(e1);
    const double v = dir.dot(r) / det;
    if (v < 0.0 || u + v > 1.0) continue;
    const double t = e2.dot(r) / det;
    if (t > 0.0 && t < best_t) {
      best_t = t;
      best = (1.0 - u - v) * a + u * b + v * c;
    }
  }
  return best;
}

// Landmark where the ray from centerline point `index` towards `direction` (made
// orthogonal to the local tangent) meets the vessel wall.
geometry::ControlPoint ostium(const ExampleVessel& vessel, std::size_t index, const Eigen::Vector3d& direction,
                              const std::string& label) {
  const Polyline& cl = vessel.centerline;
  const std::size_t i0 = index > 0 ? index - 1 : 0, i1 = std::min(index + 1, cl.size() - 1);
  const Eigen::Vector3d t = (cl[i1] - cl[i0]).normalized();
  const Eigen::Vector3d d = (direction - direction.dot(t) * t).normalized();
  const auto hit = first_hit(vessel.mesh, cl[index], d);
  if (!hit) throw std::logic_error("make_example_scene: ostium ray for " + label + " missed the " + vessel.name);
  return {label, *hit};
}

// Index of the first centerline point at or below height z (centerlines run downwards).
std::size_t first_index_below(const Polyline& centerline, double z) {
  for (std::size_t i = 0; i < centerline.size(); ++i)
    if (centerline[i].z() <= z) return i;
  return centerline.size() - 1;
}

// Whittaker smoother with clamped ends: the points x minimizing
//   sum |x_i - p_i|^2 + lambda sum |x_{i-1} - 2 x_i + x_{i+1}|^2,  x_0 = p_0, x_n = p_n,
// i.e. an elastic beam of bending stiffness lambda tied to the path by unit springs. On
// a 1 mm path it passes a bend of wavelength L with gain 1 / (1 + (2 pi l / L)^4), where
// l = lambda^(1/4) mm: bends much longer than 2 pi l are followed, shorter ones cut.
Polyline stiffen(const Polyline& path, double stiffness_length_mm) {
  const auto n = static_cast<Eigen::Index>(path.size());
  if (n < 3) return path;
  const double lambda = std::pow(stiffness_length_mm / kCenterlineStepMm, 4);
  // Unknowns are the interior points 1 .. n-2; the fixed ends move to the right side.
  const Eigen::Index m = n - 2;
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::MatrixXd rhs(m, 3);
  for (Eigen::Index i = 0; i < m; ++i) {
    entries.emplace_back(i, i, 1.0);
    rhs.row(i) = path[static_cast<std::size_t>(i + 1)].transpose();
  }
  // Second difference j uses full-path points j-1, j, j+1 (j = 1 .. n-2), i.e. unknowns
  // j-2, j-1, j; coefficients 1, -2, 1.
  for (Eigen::Index j = 1; j + 1 < n; ++j) {
    const Eigen::Index idx[3] = {j - 2, j - 1, j};
    const double coef[3] = {1.0, -2.0, 1.0};
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {
        const bool a_free = idx[a] >= 0 && idx[a] < m, b_free = idx[b] >= 0 && idx[b] < m;
        if (!a_free) continue;
        const double v = lambda * coef[a] * coef[b];
        if (b_free)
          entries.emplace_back(idx[a], idx[b], v);
        else
          rhs.row(idx[a]) -= v * path[static_cast<std::size_t>(idx[b] + 1)].transpose();
      }
    }
  }
  Eigen::SparseMatrix<double> A(m, m);
  A.setFromTriplets(entries.begin(), entries.end());
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
  if (solver.info() != Eigen::Success) throw std::logic_error("make_example_scene: device smoothing failed");
  const Eigen::MatrixXd x = solver.solve(rhs);
  Polyline out(path.size());
  out.front() = path.front();
  out.back() = path.back();
  for (Eigen::Index i = 0; i < m; ++i) out[static_cast<std::size_t>(i + 1)] = x.row(i).transpose();
  return out;
}

ExampleVessel make_aorta(const ExampleSceneParams& p, Perturbation& jitter) {
  const double top = p.aorta_top_z_mm;
  const double zc = p.aneurysm_centre_z_mm + jitter(4.0);
  const double sac_length = p.aneurysm_length_mm + jitter(6.0);
  const double sac_radius = p.aneurysm_max_radius_mm + jitter(2.0);
  const double bow_anterior = p.aorta_bow_anterior_mm + jitter(2.0);
  const double bow_left = p.aorta_bow_left_mm + jitter(2.0);

  ExampleVessel aorta;
  aorta.name = "aorta";
  aorta.kind = geometry::VesselKind::Aorta;
  // One smooth bow (zero at both ends) anteriorly and to the left, like an aorta lifted
  // off the spine by lordosis and pushed aside by its aneurysm; ends at the origin.
  aorta.centerline = sample_curve([&](double u) {
    const double z = top * (1.0 - u);
    const double bow = std::sin(kPi * z / top);
    return Eigen::Vector3d(bow_left * bow, -bow_anterior * bow, z);
  });
  const auto base = [&](double z) {
    return p.aorta_radius_bifurcation_mm + (p.aorta_radius_top_mm - p.aorta_radius_bifurcation_mm) * z / top;
  };
  require(sac_length > 0.0, "aneurysm length must be positive");
  require(sac_radius > base(zc), "aneurysm radius must exceed the aortic radius");
  for (const auto& x : aorta.centerline) {
    // Fusiform sac: a cos^2 bump, smooth (C1) where it meets the normal aorta.
    const double w = (x.z() - zc) / sac_length;
    const double c = std::cos(kPi * w);
    const double bump = std::abs(w) < 0.5 ? c * c : 0.0;
    aorta.radii_mm.push_back(base(x.z()) + (sac_radius - base(zc)) * bump);
  }
  return aorta;
}

ExampleVessel make_iliac(const ExampleSceneParams& p, const ExampleVessel& aorta, bool left,
                         Perturbation& jitter) {
  const double side = left ? 1.0 : -1.0;  // patient left is +x
  const double end_lateral = p.iliac_end_lateral_mm + jitter(6.0);
  const double end_anterior = p.iliac_end_anterior_mm + jitter(4.0);
  const double amp_x = p.iliac_tortuosity_x_mm + jitter(2.0);
  const double amp_y = p.iliac_tortuosity_y_mm + jitter(2.0);

  // Start inside the aorta's lower end so the two meshes overlap, as segmentations do.
  const double z0 = p.iliac_start_above_bifurcation_mm;
  const Polyline& acl = aorta.centerline;
  const std::size_t i = first_index_below(acl, z0);
  const double u0 = i > 0 ? (acl[i - 1].z() - z0) / (acl[i - 1].z() - acl[i].z()) : 0.0;
  const Eigen::Vector3d on_axis = (1.0 - u0) * acl[i > 0 ? i - 1 : 0] + u0 * acl[i];
  const Eigen::Vector3d start = on_axis + Eigen::Vector3d(side * p.iliac_start_lateral_mm, 0.0, 0.0);
  const Eigen::Vector3d end(side * end_lateral, -end_anterior, p.iliac_end_z_mm);

  ExampleVessel iliac;
  iliac.name = left ? "iliac_left" : "iliac_right";
  iliac.kind = geometry::VesselKind::Iliac;
  // Straight course from start to end plus bends that vanish, with their slopes, at
  // both ends (the sin(pi u) envelope), so the tube leaves the aorta and ends straight:
  // a lateral S (out along the common iliac, back along the external; peak amp_x) and
  // antero-posterior bends (back into the pelvis by 0.56 amp_y, forward by amp_y, back).
  constexpr double kSPeak = 0.76980035891950105;  // max of sin(2 pi u) sin(pi u) = 4 / (3 sqrt 3)
  iliac.centerline = sample_curve([&](double u) {
    Eigen::Vector3d x = start + u * (end - start);
    const double envelope = std::sin(kPi * u);
    x.x() += side * amp_x * std::sin(2.0 * kPi * u) * envelope / kSPeak;
    x.y() += amp_y * std::sin(3.0 * kPi * u) * envelope;
    return x;
  });
  const auto arc = geometry::arc_lengths(iliac.centerline);
  for (const double s : arc)
    iliac.radii_mm.push_back(p.iliac_radius_proximal_mm +
                             (p.iliac_radius_distal_mm - p.iliac_radius_proximal_mm) * s / arc.back());
  return iliac;
}

void mesh_vessel(ExampleVessel& vessel, int target_vertices) {
  const double length = geometry::arc_lengths(vessel.centerline).back();
  const TubeOptions options = tube_options_for_vertex_count(length, mean_radius(vessel.centerline, vessel.radii_mm),
                                                            target_vertices, true);
  vessel.mesh = tube_mesh(vessel.centerline, vessel.radii_mm, options);
}

// The wire follows the lumen path (aorta from the tip down, then the access iliac) only
// in the large: stiffened, it cuts across the iliac bends as a stiff wire straightens a
// tortuous artery, and across the corner at the bifurcation.
Polyline make_device(const ExampleSceneParams& p, const ExampleVessel& aorta, const ExampleVessel& iliac) {
  const Polyline& acl = aorta.centerline;
  const std::size_t i = first_index_below(acl, p.device_tip_z_mm);
  require(i > 0 && acl[i].z() < p.device_tip_z_mm, "device tip must lie within the aorta's height");
  const double u = (acl[i - 1].z() - p.device_tip_z_mm) / (acl[i - 1].z() - acl[i].z());
  Polyline path{(1.0 - u) * acl[i - 1] + u * acl[i]};
  for (std::size_t k = i; k < acl.size() && acl[k].z() > iliac.centerline.front().z(); ++k) path.push_back(acl[k]);
  path.insert(path.end(), iliac.centerline.begin(), iliac.centerline.end());
  path = geometry::resample(path, kCenterlineStepMm);
  path.back() = iliac.centerline.back();
  // Smoothing shortens the curve, so resample again to keep the 1 mm spacing.
  Polyline device = geometry::resample(stiffen(path, p.device_stiffness_length_mm), kCenterlineStepMm);
  device.back() = path.back();
  return device;
}

void check(const ExampleSceneParams& p) {
  const auto positive = [](double v) { return v > 0.0 && std::isfinite(v); };
  require(std::isfinite(p.variation) && p.variation >= 0.0, "variation must be finite and >= 0");
  require(positive(p.aorta_top_z_mm), "aorta_top_z_mm must be positive");
  require(positive(p.aorta_radius_top_mm) && positive(p.aorta_radius_bifurcation_mm), "aortic radii must be positive");
  require(positive(p.aneurysm_length_mm), "aneurysm_length_mm must be positive");
  require(positive(p.iliac_radius_proximal_mm) && positive(p.iliac_radius_distal_mm), "iliac radii must be positive");
  require(positive(p.iliac_start_above_bifurcation_mm) && p.iliac_start_above_bifurcation_mm < p.aorta_top_z_mm,
          "iliac start must lie within the aorta's height");
  require(std::isfinite(p.iliac_end_z_mm) && p.iliac_end_z_mm < -10.0, "iliac_end_z_mm must be below -10 mm");
  require(p.renal_z_mm > 0.0 && p.renal_z_mm < p.aorta_top_z_mm, "renal_z_mm must lie within the aorta");
  require(positive(p.internal_iliac_arc_mm), "internal_iliac_arc_mm must be positive");
  require(p.device_tip_z_mm > p.iliac_start_above_bifurcation_mm && p.device_tip_z_mm < p.aorta_top_z_mm,
          "device tip must lie between the iliac start and the aortic top");
  require(positive(p.device_stiffness_length_mm), "device_stiffness_length_mm must be positive");
  require(std::isfinite(p.device_thickness_mm) && p.device_thickness_mm >= 0.0, "device thickness must be >= 0");
  require(p.aorta_vertices >= 100 && p.iliac_vertices >= 100, "vertex targets must be >= 100");
}

geometry::Markup curve_markup(const std::string& name, const Polyline& points) {
  geometry::Markup m{"Curve", name, {}};
  m.points.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) m.points.push_back({name + "-" + std::to_string(i + 1), points[i]});
  return m;
}

}  // namespace

const ExampleVessel& ExampleScene::vessel(std::string_view name) const {
  for (const auto& v : vessels)
    if (v.name == name) return v;
  throw std::out_of_range("ExampleScene: no vessel named " + std::string(name));
}

DeviceClearance measure_device_clearance(const std::vector<Eigen::Vector3d>& device,
                                         const std::vector<Eigen::Vector3d>& centerline,
                                         const std::vector<double>& radii_mm) {
  if (centerline.size() < 2 || radii_mm.size() != centerline.size())
    throw std::invalid_argument("measure_device_clearance: need >= 2 centerline points and one radius each");
  const auto arc = geometry::arc_lengths(centerline);
  // Signed clearance per device point; NaN where the point is beyond the vessel's ends.
  std::vector<double> c(device.size(), std::numeric_limits<double>::quiet_NaN());
  DeviceClearance out;
  out.max_outside_mm = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < device.size(); ++i) {
    const auto proj = geometry::project_onto(centerline, device[i]);
    if (proj.beyond_start || proj.beyond_end) continue;
    c[i] = proj.distance_mm - interpolate_along(arc, radii_mm, proj.arc_length_mm);
    out.max_outside_mm = std::max(out.max_outside_mm, c[i]);
  }
  for (std::size_t i = 1; i < device.size(); ++i) {
    const double a = c[i - 1], b = c[i];
    if (std::isnan(a) || std::isnan(b) || (a <= 0.0 && b <= 0.0)) continue;
    const double len = (device[i] - device[i - 1]).norm();
    // Where the clearance changes sign within the segment, count the part outside.
    out.length_outside_mm += (a > 0.0 && b > 0.0) ? len : len * std::max(a, b) / std::abs(a - b);
  }
  if (!std::isfinite(out.max_outside_mm)) out.max_outside_mm = 0.0;  // never alongside
  return out;
}

ExampleScene make_example_scene(const ExampleSceneParams& params) {
  check(params);
  Perturbation jitter(params.seed, params.variation);
  ExampleScene scene;
  scene.device_thickness_mm = params.device_thickness_mm;
  // Fixed draw order (aorta, left, right) keeps every seed's anatomy reproducible.
  ExampleVessel aorta = make_aorta(params, jitter);
  ExampleVessel left = make_iliac(params, aorta, true, jitter);
  ExampleVessel right = make_iliac(params, aorta, false, jitter);
  mesh_vessel(aorta, params.aorta_vertices);
  mesh_vessel(left, params.iliac_vertices);
  mesh_vessel(right, params.iliac_vertices);

  const std::size_t renal = first_index_below(aorta.centerline, params.renal_z_mm);
  scene.landmarks.push_back(ostium(aorta, renal, Eigen::Vector3d::UnitX(), "renal_left"));
  scene.landmarks.push_back(ostium(aorta, renal, -Eigen::Vector3d::UnitX(), "renal_right"));
  // Internal iliac arteries leave the iliac's posterior-medial wall (+y, towards x = 0).
  for (const ExampleVessel* iliac : {&left, &right}) {
    const double side = iliac == &left ? 1.0 : -1.0;
    const auto index = static_cast<std::size_t>(std::lround(params.internal_iliac_arc_mm / kCenterlineStepMm));
    require(index + 1 < iliac->centerline.size(), "internal_iliac_arc_mm beyond the iliac's length");
    scene.landmarks.push_back(ostium(*iliac, index, Eigen::Vector3d(-side, 1.0, 0.0),
                                     iliac == &left ? "internal_iliac_left" : "internal_iliac_right"));
  }

  scene.device = make_device(params, aorta, params.device_in_left_iliac ? left : right);
  scene.vessels = {std::move(aorta), std::move(left), std::move(right)};
  for (const auto& v : scene.vessels) {
    scene.device_clearance.push_back(measure_device_clearance(scene.device, v.centerline, v.radii_mm));
    scene.device_clearance.back().vessel = v.name;
  }
  return scene;
}

void write_example_scene(const ExampleScene& scene, const std::filesystem::path& dir, geometry::MeshFormat format) {
  std::filesystem::create_directories(dir);
  const std::string ext = geometry::extension_for(format);
  geometry::SceneManifest manifest;
  for (const auto& v : scene.vessels) {
    const std::string mesh_file = v.name + ext, centerline_file = v.name + ".centerline.mrk.json";
    geometry::write_mesh(dir / mesh_file, v.mesh, format);
    geometry::write_markups(dir / centerline_file, {curve_markup(v.name + "_centerline", v.centerline)});
    manifest.vessels.push_back({v.name, geometry::to_string(v.kind), mesh_file, centerline_file});
  }
  geometry::write_markups(dir / "landmarks.mrk.json", {geometry::Markup{"Fiducial", "landmarks", scene.landmarks}});
  geometry::write_markups(dir / "device.mrk.json", {curve_markup("device", scene.device)});
  manifest.landmarks = "landmarks.mrk.json";
  if (scene.pelvis.V.rows() > 0) {
    manifest.pelvis = "pelvis" + ext;
    geometry::write_mesh(dir / manifest.pelvis, scene.pelvis, format);
  }
  manifest.device_thickness_mm = scene.device_thickness_mm;
  // The manifest last: a reader never finds a scene.json naming files not yet written.
  geometry::write_scene_manifest(dir / "scene.json", manifest);
}

geometry::Scene to_scene(const ExampleScene& ex) {
  geometry::Scene s;
  s.file = "example/scene.json";
  for (const auto& v : ex.vessels) {
    geometry::Vessel gv;
    gv.name = v.name;
    gv.kind = v.kind;
    gv.mesh_path = "example/" + v.name + ".stl";
    gv.centerline_path = "example/" + v.name + ".centerline.mrk.json";
    gv.mesh = {v.mesh, geometry::MeshFormat::StlBinary};
    gv.centerline = v.centerline;
    s.vessels.push_back(std::move(gv));
  }
  s.landmarks_path = "example/landmarks.mrk.json";
  s.landmarks = ex.landmarks;
  s.device_thickness_mm = ex.device_thickness_mm;
  if (ex.pelvis.V.rows() > 0) s.pelvis_path = "example/pelvis.stl";
  s.pelvis = ex.pelvis;
  return s;
}

}  // namespace evar::sim

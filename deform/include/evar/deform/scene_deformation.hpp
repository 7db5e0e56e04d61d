#pragma once
// The whole deformation stage of the paper (2.3) on a patient scene:
//   1. the aorta is deformed by its device handles (skeleton-based ARAP); device points
//      inside an iliac's lumen give it none (the device passes on into the iliac there);
//   2. the iliac carrying the device (found from the geometry) is deformed by its device
//      handles, its top vertices bound to the deformed aorta: each moves as the aortic
//      surface at its closest point (barycentric in the nearest aortic triangle);
//   3. aortic vertices below the bound iliac points are erased (faces removed; the vertex
//      array keeps its order);
//   4. an iliac without the device has its top bound to the aorta in the same way and
//      is deformed by ARAP with no other handle: the tether holds its distal part near
//      the registered pose, so it bends after the junction instead of swinging;
//   5. landmarks move with the surface they sit on;
//   6. what of the device the deformed vessels still leave outside is measured
//      (device_containment.hpp).
#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "evar/deform/arap_solver.hpp"
#include "evar/deform/control_points.hpp"
#include "evar/deform/device_containment.hpp"
#include "evar/deform/landmark_binding.hpp"
#include "evar/deform/mesh_proxy.hpp"
#include "evar/deform/skeleton.hpp"
#include "evar/geometry/scene.hpp"

namespace evar::deform {

struct DeformOptions {
  /// device_thickness_mm is taken from the scene; pair_in_order applies to the iliacs
  /// only (the device runs through them; in the aorta it ends anywhere), on by default,
  /// false for the paper's rays (for comparison).
  ControlPointOptions control{.pair_in_order = true};
  SkeletonOptions skeleton;
  ArapOptions arap;
  bool use_skeleton = true;      ///< false: plain surface ARAP (for comparison)
  double bind_length_mm = 3.0;   ///< iliac vertices this close to its proximal end are bound
  /// Solves per vessel: after each, handles are re-selected on the deformed surface (the
  /// vessel may have moved over device points that were inside) and added; 1 = the
  /// paper's single pass.
  int containment_rounds = 3;
  /// Length scale ℓ (mm) of a weak tether of every surface vertex to its registered
  /// position, energy Σ_i (A_i / ℓ²) |v'_i − v_i|² (A_i the vertex area): the deformation
  /// fades over about ℓ from the handles instead of the vessel moving rigidly as a whole
  /// through modes the handles barely fix. Not an anchor: no vertex is held. 50 mm is
  /// about the spacing of the aorta's tethering branches (renal, mesenteric, lumbar
  /// arteries) times two. 0 = off (the paper's pure handle-only formulation).
  double tether_length_mm = 50.0;
  /// Knot spacing of the iliacs' coarse space (coarse_space.hpp, ArapOptions::coarse_rotations);
  /// 0 = none. An iliac is long and thin, held by handles along one side of its wall and
  /// at its top: lengths of it hinge and twist about those, the motions local/global
  /// iterations are slowest on (measured: 26 iterations to come within 0.05 mm of the
  /// fixed point instead of 12). The aorta is not given one: its iterations converge in
  /// 6-9 without, and with one they cost more (docs/DEFORMATION.md).
  double coarse_knot_spacing_mm = 20.0;
  /// A vessel mesh whose median edge is under 3/4 of this (mm) is solved on a coarser
  /// proxy with edges of about this length, and the fine mesh follows it (mesh_proxy.hpp):
  /// on a fine mesh ARAP's membrane crumples and the cost grows as n^1.3, while the
  /// result at the paper's resolution (its 7,500-vertex aorta has edges of about 1.4 mm)
  /// does not depend on how finely CT was meshed. 0 = every mesh is solved as it is.
  double proxy_edge_mm = 1.4;
  /// The iliacs (independent once the aorta is solved) on threads of their own; false:
  /// one after the other on the calling thread. The result is the same either way.
  bool parallel_iliacs = true;
};

struct StageTimings {
  double weights_ms = 0, control_points_ms = 0, skeleton_ms = 0, factor_ms = 0, iterate_ms = 0, total_ms = 0;
};

struct VesselReport {
  std::string name;
  std::string kind;
  std::string role;              ///< "deformed", "carries the device", "follows the aorta", "unchanged"
  int vertices = 0, faces = 0;
  int proxy_vertices = 0;        ///< the proxy it was solved on (0: solved on its own mesh)
  double proxy_edge_mm = 0.0;    ///< the proxy's edge: the asked one, or finer where the vessel was too thin for it
  std::string proxy_refused;     ///< why a mesh fine enough for a proxy is solved as it is ("" otherwise)
  std::string proxy_file;        ///< the scene's proxy file it was read from ("" when made here, or none)
  std::string proxy_file_unused; ///< why the scene's proxy file was not used, the proxy made anew ("" otherwise)
  int device_points = 0;         ///< device samples that lie within this vessel's reach
  int control_points = 0;        ///< handles from the device
  int bound_vertices = 0;        ///< iliac top vertices bound to the aorta
  double junction_gap_mm = 0.0;  ///< the farthest of them from its point on the undeformed aortic surface
  int constrained_vertices = 0;
  int skeleton_points = 0;       ///< plane centres + wall hits
  int rounds = 0;                ///< containment rounds solved
  int iterations = 0;            ///< ARAP iterations, all rounds
  int anderson_rejections = 0;   ///< accelerated steps the energy safeguard refused, all rounds
  int coarse_fallbacks = 0;      ///< steps where the coarse-turned rotations raised E, all rounds
  bool converged = true;
  double final_energy = 0.0;
  double max_displacement_mm = 0.0;
  int erased_vertices = 0, erased_faces = 0;
  StageTimings timings;
};

struct DeformedVessel {
  geometry::TriangleMesh mesh;        ///< deformed vertices (all, original order); faces minus erased ones
  std::vector<char> erased;           ///< per vertex: erased (1) or kept (0)
};

struct SceneDeformation {
  std::vector<DeformedVessel> vessels;            ///< same order as scene.vessels
  std::vector<geometry::ControlPoint> landmarks;  ///< moved, labels kept
  /// The vessel each landmark follows: the one it sits on, or the carrier iliac for one
  /// on the erased aortic stump (the iliac now represents that part of the aorta).
  std::vector<std::string> landmark_vessel;
  std::vector<VesselReport> reports;
  std::string device_iliac;                       ///< empty if the device reaches no iliac
  /// The device against the deformed vessels (the fine meshes, erased faces removed).
  DeviceContainment containment;
  double containment_ms = 0.0;                    ///< measuring it (part of total_ms)
  /// deform_scene only: preparing the scene's solver (paid once per scene; proxies
  /// included) and, of it, the proxies; the rest of total_ms is the call for this device.
  double precompute_ms = 0.0, proxy_ms = 0.0;
  double total_ms = 0.0;
  /// Per vessel, the proxy's solved vertices (no rows for a vessel solved on its own
  /// mesh): the next frame of a live sequence starts from them.
  std::vector<geometry::Vertices> proxy_solutions;
};

/// The scene with everything that does not depend on the device precomputed per vessel
/// (ray-casting BVH, skeleton and radius profile, cotangent weights, ARAP terms, tether,
/// assembled matrix and its fill-reducing ordering), so each new device pose only costs
/// control points, a numeric factorization and the iterations. The scene must outlive it.
class SceneDeformer {
 public:
  /// Throws base::InputError when a vessel's centerline does not run inside its mesh.
  SceneDeformer(const geometry::Scene& scene, DeformOptions options = {});
  ~SceneDeformer();
  SceneDeformer(const SceneDeformer&) = delete;
  SceneDeformer& operator=(const SceneDeformer&) = delete;

  /// Throws base::InputError when the device is unusable (fewer than 2 points, not
  /// finite, or nowhere near any vessel) and std::runtime_error when a solve fails.
  /// In the reports, weights_ms and skeleton_ms are the precomputation's (the constructor),
  /// the other stages this call's; total_ms of a vessel is their sum (its cold cost) and
  /// SceneDeformation::total_ms is this call's wall time.
  ///
  /// `previous`: the result for the previous device pose of a live sequence. Each vessel's
  /// solve then starts from its shape there instead of from Laplacian editing, which
  /// saves iterations when the device moved little and keeps consecutive overlays
  /// coherent. The fixed point is the same; the result differs by less than the
  /// stopping rule's distance to it.
  SceneDeformation deform(const geometry::Polyline& device, const SceneDeformation* previous = nullptr) const;
  double precompute_ms() const { return precompute_ms_; }
  /// Of precompute_ms: making the proxies of fine meshes (or reading them from the scene's
  /// proxy files).
  double proxy_ms() const { return proxy_ms_; }
  /// The scene it deforms (as given, fine meshes).
  const geometry::Scene& scene() const { return original_; }
  /// Lumen radius of vessel `vessel` (scene order) at `arc_length_mm` along its centerline:
  /// the radius profile of its skeleton, as the control points use it (precomputed).
  double lumen_radius_mm(std::size_t vessel, double arc_length_mm) const;
  /// The vessel's proxy (null when it is solved on its own mesh).
  const MeshProxy* proxy(std::size_t vessel) const { return proxies_[vessel] ? &*proxies_[vessel] : nullptr; }
  /// Why vessel i needed a proxy and has none ("" when it has one or needs none).
  const std::string& proxy_refused(std::size_t vessel) const { return proxy_refusals_[vessel]; }
  /// Where vessel i's proxy came from: the scene's proxy file when it was read from there,
  /// and why a proxy file the scene names was not used (each "" otherwise).
  struct ProxyOrigin {
    std::string file, unused;
  };
  const ProxyOrigin& proxy_origin(std::size_t vessel) const { return proxy_origins_[vessel]; }

  struct VesselModel;  ///< opaque per-vessel precomputation

 private:
  /// The stages 1-5 on the fine meshes (through their proxies where they have one).
  SceneDeformation deform_vessels(const geometry::Polyline& device, const SceneDeformation* previous) const;
  /// The stages 1-5 on the working scene (proxies in place of fine meshes).
  SceneDeformation solve(const geometry::Polyline& device, const SceneDeformation* previous) const;

  const geometry::Scene& original_;
  DeformOptions options_;
  std::vector<std::optional<MeshProxy>> proxies_;  ///< per vessel
  std::vector<std::string> proxy_refusals_;        ///< per vessel, see proxy_refused()
  std::vector<ProxyOrigin> proxy_origins_;         ///< per vessel, see proxy_origin()
  double proxy_ms_ = 0.0;                          ///< making them (part of precompute_ms_)
  std::unique_ptr<geometry::Scene> working_;       ///< the scene with the proxies (null: none)
  const geometry::Scene& scene_;                   ///< *working_ or original_
  std::vector<std::unique_ptr<VesselModel>> models_;
  /// Per landmark: the vessel whose surface it sits on, and its binding to every vessel
  /// (scene-only); the carrier iliac's is used when its aortic face is erased.
  struct LandmarkBinding {
    std::size_t vessel = 0;
    std::vector<SurfaceBinding> on;  ///< per vessel
  };
  std::vector<LandmarkBinding> landmark_bindings_;
  /// Per vessel, per fine vertex: past its centerline's ends (the caps a segmentation
  /// closes a vessel with where it stopped following it). Faces touching one are left out
  /// of the containment check: the lumen goes on there, the wall does not.
  std::vector<std::vector<char>> past_centerline_ends_;
  /// Per vessel: its faces wind inward (normals toward the centerline, as VMTK writes its
  /// surfaces); the containment check turns them.
  std::vector<char> wound_inward_;
  double precompute_ms_ = 0.0;
};

/// SceneDeformer(scene, options).deform(device), with the precomputation's stage timings
/// (weights, skeleton) added to each vessel's report and to total_ms.
SceneDeformation deform_scene(const geometry::Scene& scene, const geometry::Polyline& device,
                              const DeformOptions& options = {});

}  // namespace evar::deform

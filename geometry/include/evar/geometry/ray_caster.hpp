#pragma once
// Ray queries against one triangle mesh, backed by an Embree 3 BVH (single precision
// inside Embree; hit points are recomputed in double from the barycentric coordinates).
#include <Eigen/Core>
#include <memory>
#include <limits>
#include <optional>

#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::geometry {

struct RayHit {
  double t_mm;                 ///< distance along the unit direction
  int face;                    ///< triangle index
  Eigen::Vector3d barycentric; ///< weights of F(face, 0..2)
  Eigen::Vector3d point;       ///< mm
};

class RayCaster {
 public:
  /// How much effort the BVH build spends: High for a mesh queried many times (the
  /// preoperative vessels), Low for a one-off check of a deformed mesh (builds several
  /// times faster, queries a little slower).
  enum class BuildQuality { Low, High };

  /// Builds the BVH over `mesh` (copied into Embree's buffers; the mesh may go away).
  explicit RayCaster(const TriangleMesh& mesh, BuildQuality quality = BuildQuality::High);
  ~RayCaster();
  RayCaster(const RayCaster&) = delete;
  RayCaster& operator=(const RayCaster&) = delete;
  RayCaster(RayCaster&&) noexcept;
  RayCaster& operator=(RayCaster&&) noexcept;

  /// First hit with t in (t_min, t_max] along `direction` (normalized internally).
  std::optional<RayHit> first_hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                  double t_max = std::numeric_limits<double>::infinity(),
                                  double t_min = 0.0) const;

  /// Number of surface crossings along the whole ray from `origin`.
  int crossings(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const;

  /// The mesh it was built over (its copy, in double).
  const TriangleMesh& mesh() const;

  /// Inside test for a closed mesh by ray parity, voted over three fixed directions.
  bool contains(const Eigen::Vector3d& point) const;

  /// The closest point of the mesh to `point` within `max_distance_mm` (nullopt when no
  /// face comes that close, or for a non-finite point): the same answer as
  /// closest_point_on_mesh, found through the BVH (Embree's point query) in about
  /// log(#F) instead of a scan of the faces.
  std::optional<SurfacePoint> closest_point(const Eigen::Vector3d& point,
                                            double max_distance_mm = std::numeric_limits<double>::infinity()) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace evar::geometry

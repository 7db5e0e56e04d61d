#include "evar/geometry/ray_caster.hpp"

#include <embree3/rtcore.h>

#include "evar/geometry/closest_point.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace evar::geometry {
namespace {

struct DeviceDeleter {
  void operator()(RTCDeviceTy* d) const { rtcReleaseDevice(d); }
};
struct SceneDeleter {
  void operator()(RTCSceneTy* s) const { rtcReleaseScene(s); }
};
using DeviceHandle = std::unique_ptr<RTCDeviceTy, DeviceDeleter>;
using SceneHandle = std::unique_ptr<RTCSceneTy, SceneDeleter>;

// One Embree device for the process: creating one is costly and it is thread safe.
// threads=1 keeps BVH builds on the calling thread (the node schedules its own work).
// Different scenes are built and traced from several threads at once on it (the two
// iliacs are deformed in parallel); Embree allows that for distinct scenes.
RTCDevice shared_device() {
  static const DeviceHandle device = [] {
    RTCDevice d = rtcNewDevice("threads=1");
    if (!d) throw std::runtime_error("Embree: cannot create a device (error " +
                                     std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")");
    return DeviceHandle(d);
  }();
  return device.get();
}

// A ray in the BVH's frame; `o` already relative to the mesh's centre. Embree requires
// 0 <= tnear <= tfar (a negative tnear aborts some builds of it).
RTCRayHit make_ray(const Eigen::Vector3d& o, const Eigen::Vector3d& d, float t_min, float t_max) {
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(o.x());
  rh.ray.org_y = static_cast<float>(o.y());
  rh.ray.org_z = static_cast<float>(o.z());
  rh.ray.dir_x = static_cast<float>(d.x());
  rh.ray.dir_y = static_cast<float>(d.y());
  rh.ray.dir_z = static_cast<float>(d.z());
  rh.ray.tnear = t_min;
  rh.ray.tfar = t_max;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.flags = 0;
  rh.ray.time = 0.0f;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

}  // namespace

struct RayCaster::Impl {
  SceneHandle scene;
  TriangleMesh mesh;  // kept in double to recompute hit points exactly
  // Embree holds the vertices relative to this point (the middle of the mesh's box): in
  // single precision, CT coordinates a metre from the scanner's origin would otherwise
  // lose a hundred times more than the mesh's own extent does.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();

  // The first hit along the unit direction d with t in [t_min, t_max] (floats, as Embree
  // traces them); geomID is RTC_INVALID_GEOMETRY_ID when there is none.
  RTCRayHit trace(const Eigen::Vector3d& origin, const Eigen::Vector3d& d, float t_min, float t_max) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh = make_ray(origin - centre, d, t_min, t_max);
    rtcIntersect1(scene.get(), &ctx, &rh);
    return rh;
  }
};

namespace {
// The unit direction of a ray that can be traced: a finite, non-zero direction from a
// finite origin (nullopt otherwise).
std::optional<Eigen::Vector3d> unit_direction(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) {
  const double len = direction.norm();
  if (!(len > 0.0) || !std::isfinite(len) || !origin.allFinite()) return std::nullopt;
  return Eigen::Vector3d(direction / len);
}

// A non-negative float bound for Embree from a double one (not NaN).
float float_bound(double t) {
  if (t <= 0.0) return 0.0f;
  return std::isfinite(t) ? static_cast<float>(t) : std::numeric_limits<float>::infinity();
}
}  // namespace

RayCaster::RayCaster(const TriangleMesh& mesh, BuildQuality quality) : impl_(std::make_unique<Impl>()) {
  RTCDevice device = shared_device();
  impl_->mesh = mesh;
  impl_->scene.reset(rtcNewScene(device));
  rtcSetSceneFlags(impl_->scene.get(), RTC_SCENE_FLAG_ROBUST);
  const RTCBuildQuality q = quality == BuildQuality::Low ? RTC_BUILD_QUALITY_LOW : RTC_BUILD_QUALITY_MEDIUM;
  rtcSetSceneBuildQuality(impl_->scene.get(), q);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetGeometryBuildQuality(geom, q);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                         3 * sizeof(float), static_cast<std::size_t>(mesh.V.rows())));
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                            3 * sizeof(unsigned), static_cast<std::size_t>(mesh.F.rows())));
  if (!vb || !ib) {
    rtcReleaseGeometry(geom);
    throw std::runtime_error("Embree: cannot allocate geometry buffers");
  }
  if (mesh.V.rows() > 0) impl_->centre = 0.5 * (mesh.V.colwise().minCoeff() + mesh.V.colwise().maxCoeff()).transpose();
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i)
    for (int k = 0; k < 3; ++k) vb[3 * i + k] = static_cast<float>(mesh.V(i, k) - impl_->centre(k));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) ib[3 * f + k] = static_cast<unsigned>(mesh.F(f, k));
  rtcCommitGeometry(geom);
  rtcAttachGeometry(impl_->scene.get(), geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(impl_->scene.get());
  if (const RTCError err = rtcGetDeviceError(device); err != RTC_ERROR_NONE)
    throw std::runtime_error("Embree: scene build failed (error " + std::to_string(static_cast<int>(err)) + ")");
}

RayCaster::~RayCaster() = default;
RayCaster::RayCaster(RayCaster&&) noexcept = default;
RayCaster& RayCaster::operator=(RayCaster&&) noexcept = default;

std::optional<RayHit> RayCaster::first_hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                           double t_max, double t_min) const {
  const auto unit = unit_direction(origin, direction);
  if (!unit || std::isnan(t_min) || std::isnan(t_max)) return std::nullopt;
  const Eigen::Vector3d& d = *unit;
  const float lo = float_bound(t_min), hi = float_bound(t_max);
  if (!(lo <= hi)) return std::nullopt;
  const RTCRayHit rh = impl_->trace(origin, d, lo, hi);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  RayHit hit;
  hit.face = static_cast<int>(rh.hit.primID);
  const double u = rh.hit.u, v = rh.hit.v;
  hit.barycentric = {1.0 - u - v, u, v};
  const auto& F = impl_->mesh.F;
  const auto& V = impl_->mesh.V;
  hit.point = hit.barycentric[0] * V.row(F(hit.face, 0)).transpose() +
              hit.barycentric[1] * V.row(F(hit.face, 1)).transpose() +
              hit.barycentric[2] * V.row(F(hit.face, 2)).transpose();
  hit.t_mm = (hit.point - origin).dot(d);
  return hit;
}

int RayCaster::crossings(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const {
  const auto unit = unit_direction(origin, direction);
  if (!unit) return 0;
  // Each next ray starts just past the last hit's distance as Embree computed it (the same
  // float ray each time), so no hit comes back; a distance recomputed in double would not
  // match Embree's rounding and could return the same hit again. Triangles meeting at the
  // crossing point (a shared edge) usually give the same distance and count once; where
  // they do not, the three-direction vote in contains() absorbs it.
  int count = 0;
  float t = 0.0f;
  for (int guard = 0; guard < 100000; ++guard) {
    const RTCRayHit rh = impl_->trace(origin, *unit, t, std::numeric_limits<float>::infinity());
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) break;
    ++count;
    t = std::nextafter(rh.ray.tfar, std::numeric_limits<float>::infinity());
    if (!std::isfinite(t)) break;
  }
  return count;
}

const TriangleMesh& RayCaster::mesh() const { return impl_->mesh; }

bool RayCaster::contains(const Eigen::Vector3d& point) const {
  // Irrational-ish directions avoid grazing axis-aligned mesh features.
  static const Eigen::Vector3d dirs[3] = {Eigen::Vector3d(0.5773, 0.6137, 0.5385).normalized(),
                                          Eigen::Vector3d(-0.7071, 0.1013, -0.6999).normalized(),
                                          Eigen::Vector3d(0.1234, -0.9123, 0.3902).normalized()};
  int inside_votes = 0;
  for (const auto& d : dirs) inside_votes += crossings(point, d) % 2;
  return inside_votes >= 2;
}

namespace {
// What a point query carries to its callback: the query in double (the BVH holds floats
// about `centre`), and the best answer so far.
struct ClosestQuery {
  const TriangleMesh* mesh;
  Eigen::Vector3d point;
  double limit_mm;
  SurfacePoint best;  // face -1 until a face within limit_mm is found
};

// Called by Embree for each triangle whose box reaches the query's sphere: the exact
// closest point of that triangle, in double; shrinking the radius prunes the rest.
bool closest_on_primitive(RTCPointQueryFunctionArguments* args) {
  auto* q = static_cast<ClosestQuery*>(args->userPtr);
  const int f = static_cast<int>(args->primID);
  const auto& F = q->mesh->F;
  const auto& V = q->mesh->V;
  const Eigen::Vector3d a = V.row(F(f, 0)).transpose(), b = V.row(F(f, 1)).transpose(), c = V.row(F(f, 2)).transpose();
  const Eigen::Vector3d w = closest_point_on_triangle(q->point, a, b, c);
  const Eigen::Vector3d x = w[0] * a + w[1] * b + w[2] * c;
  const double d = (x - q->point).norm();
  if (d > q->limit_mm || (q->best.face >= 0 && !(d < q->best.distance_mm))) return false;
  q->best = {f, w, x, d};
  // The sphere in floats must not cut off a face that rounding puts a hair farther away.
  args->query->radius = std::nextafter(static_cast<float>(d), std::numeric_limits<float>::infinity()) * 1.000001f;
  return true;
}
}  // namespace

std::optional<SurfacePoint> RayCaster::closest_point(const Eigen::Vector3d& point, double max_distance_mm) const {
  if (!point.allFinite() || std::isnan(max_distance_mm) || max_distance_mm < 0.0 || impl_->mesh.F.rows() == 0)
    return std::nullopt;
  ClosestQuery q{&impl_->mesh, point, max_distance_mm, {}};
  const Eigen::Vector3d local = point - impl_->centre;
  RTCPointQuery query;
  query.x = static_cast<float>(local.x());
  query.y = static_cast<float>(local.y());
  query.z = static_cast<float>(local.z());
  query.time = 0.0f;
  query.radius = std::isfinite(max_distance_mm) ? static_cast<float>(max_distance_mm) * 1.000001f + 1e-6f
                                                : std::numeric_limits<float>::infinity();
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  rtcPointQuery(impl_->scene.get(), &query, &context, closest_on_primitive, &q);
  if (q.best.face < 0) return std::nullopt;
  return q.best;
}

}  // namespace evar::geometry

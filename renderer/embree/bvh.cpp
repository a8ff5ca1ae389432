#include "renderer/embree/bvh.h"

#include <embree3/rtcore.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/util/log.h"
#include "renderer/embree/build_choice.h"

namespace rayfarm {
namespace {

void log_device_error(void* /*user*/, RTCError code, const char* message) {
  get_logger("embree")->error("Embree error {}: {}", static_cast<int>(code),
                              message ? message : "");
}

// Embree's FLT_LARGE: a ray whose origin or direction has a component beyond it is invalid, and
// Debian's Embree build asserts on it (the process aborts).
constexpr float kEmbreeLarge = 1.844e18f;

bool within_embree_range(const Vec3& v) {
  return std::fabs(v.x) <= kEmbreeLarge && std::fabs(v.y) <= kEmbreeLarge &&
         std::fabs(v.z) <= kEmbreeLarge;
}

/// Copies `ray` into Embree's form. A direction beyond Embree's range is divided by a power of
/// two, and t multiplied by it: exact, so the ray is the same line. Returns false when the ray
/// cannot be traced at all (origin out of range, or anything not finite); `t_scale` receives
/// the factor that Embree's t must be divided by.
bool to_embree(const Ray& ray, RTCRay& r, float& t_scale) {
  t_scale = 1.f;
  constexpr float kUnscaled = 0x1p60f;  // larger direction components are rescaled
  Vec3 dir = ray.dir;
  // Nearly every ray passes all the checks at once: origin within Embree's range and a direction
  // that needs no rescaling (both comparisons false for NaN and infinities), t not NaN.
  const bool plain = std::fabs(ray.org.x) <= kEmbreeLarge && std::fabs(ray.org.y) <= kEmbreeLarge &&
                     std::fabs(ray.org.z) <= kEmbreeLarge && std::fabs(dir.x) <= kUnscaled &&
                     std::fabs(dir.y) <= kUnscaled && std::fabs(dir.z) <= kUnscaled &&
                     !std::isnan(ray.tnear) && !std::isnan(ray.tfar);
  if (!plain) {
    if (!is_finite(ray.org) || !is_finite(ray.dir) || !within_embree_range(ray.org) ||
        std::isnan(ray.tnear) || std::isnan(ray.tfar)) {
      return false;
    }
    const float largest = max_component(abs(dir));
    if (largest > kUnscaled) {
      int exponent = 0;
      std::frexp(largest, &exponent);
      t_scale = std::ldexp(1.f, exponent - 60);  // largest / t_scale <= 2^60
      dir = dir / t_scale;
    }
  }
  r.org_x = ray.org.x;
  r.org_y = ray.org.y;
  r.org_z = ray.org.z;
  r.dir_x = dir.x;
  r.dir_y = dir.y;
  r.dir_z = dir.z;
  r.tnear = ray.tnear * t_scale;
  r.tfar = ray.tfar * t_scale;  // may become +inf, which Embree accepts
  r.time = ray.time;
  r.mask = 0xffffffffu;
  r.id = 0;
  r.flags = 0;
  return true;
}

// The box of a mesh's triangles (over every pose of a moving one), for build_geometries_apart():
// its vertices that triangles use, since a file may carry others.
BuildBox mesh_box(const Bvh::Mesh& mesh) {
  BuildBox box;
  const auto add_pose = [&](const std::vector<Vec3>& positions) {
    for (uint32_t i : *mesh.indices) {
      if (i < positions.size()) box.add(positions[i]);
    }
  };
  if (mesh.poses != nullptr) {
    for (const std::vector<Vec3>& pose : *mesh.poses) add_pose(pose);
  } else {
    add_pose(*mesh.positions);
  }
  return box;
}

// The build quality that selects the build of build_choice.h: Embree builds a scene's geometries
// apart (two-level) at low quality, as one tree with spatial splits at high.
RTCBuildQuality build_quality(const std::vector<BuildBox>& boxes) {
  return build_geometries_apart(boxes) ? RTC_BUILD_QUALITY_LOW : RTC_BUILD_QUALITY_HIGH;
}

// Builds `scene`'s BVH. The two-level build gathers its geometries' trees into a list in
// parallel, in the order threads happen to finish, and that order can shape the top of the tree
// (where boxes tie) and so decide which of two surfaces at exactly the same distance a ray
// reports. Built on one thread it gathers them in geometry order, and every worker builds the
// same tree. (It is the fast build: 29 ms on two threads for 80,000 triangles, where the
// spatial-split build takes 75 ms.)
void commit_scene(RTCScene scene, RTCBuildQuality quality) {
  if (quality == RTC_BUILD_QUALITY_LOW) {
    tbb::task_arena one_thread(1);
    one_thread.execute([scene] { rtcCommitScene(scene); });
  } else {
    rtcCommitScene(scene);
  }
}

[[noreturn]] void fail(RTCDevice device, const std::string& what) {
  const RTCError code = rtcGetDeviceError(device);
  throw std::runtime_error("Embree: " + what + " failed (error " + std::to_string(code) + ")");
}

// Owning handles: whatever throws while the BVH is built releases what was made so far.
struct ReleaseDevice {
  void operator()(RTCDevice d) const { rtcReleaseDevice(d); }
};
struct ReleaseScene {
  void operator()(RTCScene s) const { rtcReleaseScene(s); }
};
struct ReleaseGeometry {
  void operator()(RTCGeometry g) const { rtcReleaseGeometry(g); }
};
using DeviceHandle = std::unique_ptr<RTCDeviceTy, ReleaseDevice>;
using SceneHandle = std::unique_ptr<RTCSceneTy, ReleaseScene>;
using GeometryHandle = std::unique_ptr<RTCGeometryTy, ReleaseGeometry>;

// What a filtered geometry's callback receives: the scene's filter and the geometry's RayHit id.
struct FilterTarget {
  Bvh::HitFilter filter;
  uint32_t geom;
};

// Embree calls this for every candidate hit of a filtered geometry, closest-hit and shadow rays
// alike; clearing valid[0] makes it pass through. Single rays only (rtcIntersect1, rtcOccluded1).
void filter_hit(const RTCFilterFunctionNArguments* args) {
  const auto* target = static_cast<const FilterTarget*>(args->geometryUserPtr);
  if (args->valid[0] == 0) return;
  // The point on the ray: Embree's t with its (possibly rescaled) direction gives the same line.
  const float t = RTCRayN_tfar(args->ray, args->N, 0);
  const Vec3 p(RTCRayN_org_x(args->ray, args->N, 0) + t * RTCRayN_dir_x(args->ray, args->N, 0),
               RTCRayN_org_y(args->ray, args->N, 0) + t * RTCRayN_dir_y(args->ray, args->N, 0),
               RTCRayN_org_z(args->ray, args->N, 0) + t * RTCRayN_dir_z(args->ray, args->N, 0));
  if (!target->filter.keep(target->filter.context, target->geom,
                           RTCHitN_primID(args->hit, args->N, 0), RTCHitN_u(args->hit, args->N, 0),
                           RTCHitN_v(args->hit, args->N, 0), p,
                           RTCRayN_time(args->ray, args->N, 0))) {
    args->valid[0] = 0;
  }
}

}  // namespace

struct Bvh::Impl {
  // Declared in this order so that the scene is released before its device.
  DeviceHandle device;
  std::vector<SceneHandle> groups;  // one scene per group, released before the device
  SceneHandle scene;
  uint32_t sphere_id = RTC_INVALID_GEOMETRY_ID;  // Embree's id of the sphere set (after the meshes)
  std::vector<std::unique_ptr<FilterTarget>> filters;  // stable addresses for Embree's user data

  void set_filter(const GeometryHandle& geometry, const HitFilter* filter, uint32_t geom) {
    if (filter == nullptr) return;
    if (!rtcGetDeviceProperty(device.get(), RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED))
      throw std::runtime_error("Embree: this build has no filter functions, which cut-outs need");
    filters.push_back(std::make_unique<FilterTarget>(FilterTarget{*filter, geom}));
    rtcSetGeometryUserData(geometry.get(), filters.back().get());
    rtcSetGeometryIntersectFilterFunction(geometry.get(), filter_hit);
    rtcSetGeometryOccludedFilterFunction(geometry.get(), filter_hit);
  }
  uint32_t instance_base = 0;  // Embree's id of instance 0 (after the spheres)
  std::vector<BuildBox> group_boxes;  // each group's box, in its own coordinates

  // The boxes of the world's geometries (each mesh, the sphere set, each instance over its
  // poses), after the groups were added.
  std::vector<BuildBox> world_boxes(const std::vector<Mesh>& meshes,
                                    const std::vector<SphereInput>& spheres,
                                    const std::vector<std::vector<SphereInput>>& sphere_poses,
                                    const std::vector<InstanceInput>& instances) const {
    std::vector<BuildBox> boxes;
    for (const Mesh& mesh : meshes) boxes.push_back(mesh_box(mesh));
    BuildBox sphere_box;
    const auto add_spheres = [&sphere_box](const std::vector<SphereInput>& at) {
      for (const SphereInput& s : at) {
        sphere_box.add(s.center - Vec3(s.radius));
        sphere_box.add(s.center + Vec3(s.radius));
      }
    };
    add_spheres(spheres);
    for (const std::vector<SphereInput>& pose : sphere_poses) add_spheres(pose);
    boxes.push_back(sphere_box);
    for (const InstanceInput& instance : instances) {
      const BuildBox& local = group_boxes.at(instance.group);
      BuildBox box;
      const auto place = [&](const std::array<float, 12>& m) {
        if (local.empty()) return;
        for (int corner = 0; corner < 8; ++corner) {
          const Vec3 c((corner & 1) ? local.hi.x : local.lo.x, (corner & 2) ? local.hi.y : local.lo.y,
                       (corner & 4) ? local.hi.z : local.lo.z);
          box.add(Vec3(m[0] * c.x + m[1] * c.y + m[2] * c.z + m[3],
                       m[4] * c.x + m[5] * c.y + m[6] * c.z + m[7],
                       m[8] * c.x + m[9] * c.y + m[10] * c.z + m[11]));
        }
      };
      if (instance.poses.empty()) place(instance.world_from_object);
      for (const std::array<float, 12>& pose : instance.poses) place(pose);
      boxes.push_back(box);
    }
    return boxes;
  }

  GeometryHandle new_geometry(RTCGeometryType type, const char* what) {
    GeometryHandle geometry(rtcNewGeometry(device.get(), type));
    if (!geometry) fail(device.get(), what);
    return geometry;
  }

  void add_mesh(const Mesh& mesh, uint32_t id) { add_mesh_to(scene.get(), mesh, id); }

  void add_mesh_to(RTCScene target, const Mesh& mesh, uint32_t id) {
    const GeometryHandle geometry =
        new_geometry(RTC_GEOMETRY_TYPE_TRIANGLE, "rtcNewGeometry(triangle)");
    const size_t triangle_count = mesh.indices->size() / 3;
    const size_t steps = mesh.poses != nullptr ? mesh.poses->size() : 1;
    rtcSetGeometryTimeStepCount(geometry.get(), static_cast<unsigned>(steps));
    for (size_t step = 0; step < steps; ++step) {
      const std::vector<Vec3>& positions =
          mesh.poses != nullptr ? (*mesh.poses)[step] : *mesh.positions;
      const size_t vertex_count = positions.size();
      // Embree reads 16 bytes per vertex; the extra float pads the last one.
      auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
          geometry.get(), RTC_BUFFER_TYPE_VERTEX, static_cast<unsigned>(step), RTC_FORMAT_FLOAT3,
          3 * sizeof(float), vertex_count + 1));
      if (!vertices) fail(device.get(), "triangle buffer allocation");
      for (size_t i = 0; i < vertex_count; ++i) {
        const Vec3& p = positions[i];
        vertices[3 * i] = p.x;
        vertices[3 * i + 1] = p.y;
        vertices[3 * i + 2] = p.z;
      }
    }
    auto* indices = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geometry.get(), RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(uint32_t), triangle_count));
    if (!indices) fail(device.get(), "triangle buffer allocation");
    std::copy(mesh.indices->begin(), mesh.indices->end(), indices);
    set_filter(geometry, mesh.filter, id);
    commit_and_attach_to(target, geometry, id);
  }

  void add_group(const std::vector<Mesh>& meshes) {
    SceneHandle group(rtcNewScene(device.get()));
    if (!group) fail(device.get(), "rtcNewScene(group)");
    std::vector<BuildBox> boxes;
    for (const Mesh& mesh : meshes) boxes.push_back(mesh_box(mesh));
    const RTCBuildQuality quality = build_quality(boxes);
    rtcSetSceneBuildQuality(group.get(), quality);
    BuildBox all;
    for (const BuildBox& b : boxes) all.add(b);
    group_boxes.push_back(all);
    for (uint32_t i = 0; i < meshes.size(); ++i) {
      if (!meshes[i].indices->empty()) add_mesh_to(group.get(), meshes[i], i);
    }
    commit_scene(group.get(), quality);
    if (rtcGetDeviceError(device.get()) != RTC_ERROR_NONE) fail(device.get(), "group commit");
    groups.push_back(std::move(group));
  }

  void add_instance(const InstanceInput& instance, uint32_t id) {
    const GeometryHandle geometry =
        new_geometry(RTC_GEOMETRY_TYPE_INSTANCE, "rtcNewGeometry(instance)");
    rtcSetGeometryInstancedScene(geometry.get(), groups.at(instance.group).get());
    if (instance.poses.empty()) {
      rtcSetGeometryTimeStepCount(geometry.get(), 1);
      rtcSetGeometryTransform(geometry.get(), 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR,
                              instance.world_from_object.data());
    } else {
      rtcSetGeometryTimeStepCount(geometry.get(), static_cast<unsigned>(instance.poses.size()));
      for (size_t step = 0; step < instance.poses.size(); ++step)
        rtcSetGeometryTransform(geometry.get(), static_cast<unsigned>(step),
                                RTC_FORMAT_FLOAT3X4_ROW_MAJOR, instance.poses[step].data());
    }
    commit_and_attach(geometry, id);
  }

  void add_spheres(const std::vector<SphereInput>& spheres,
                   const std::vector<std::vector<SphereInput>>& poses, uint32_t id,
                   const HitFilter* filter) {
    const GeometryHandle geometry =
        new_geometry(RTC_GEOMETRY_TYPE_SPHERE_POINT, "rtcNewGeometry(sphere)");
    const size_t steps = poses.empty() ? 1 : poses.size();
    rtcSetGeometryTimeStepCount(geometry.get(), static_cast<unsigned>(steps));
    for (size_t step = 0; step < steps; ++step) {
      const std::vector<SphereInput>& at = poses.empty() ? spheres : poses[step];
      auto* points = static_cast<float*>(rtcSetNewGeometryBuffer(
          geometry.get(), RTC_BUFFER_TYPE_VERTEX, static_cast<unsigned>(step), RTC_FORMAT_FLOAT4,
          4 * sizeof(float), at.size()));
      if (!points) fail(device.get(), "sphere buffer allocation");
      for (size_t i = 0; i < at.size(); ++i) {
        points[4 * i] = at[i].center.x;
        points[4 * i + 1] = at[i].center.y;
        points[4 * i + 2] = at[i].center.z;
        points[4 * i + 3] = at[i].radius;
      }
    }
    sphere_id = id;
    set_filter(geometry, filter, kSphereGeometry);
    commit_and_attach(geometry, id);
  }

  // The scene holds its own reference to an attached geometry; ours goes with the handle.
  void commit_and_attach(const GeometryHandle& geometry, uint32_t id) {
    commit_and_attach_to(scene.get(), geometry, id);
  }
  void commit_and_attach_to(RTCScene target, const GeometryHandle& geometry, uint32_t id) {
    rtcCommitGeometry(geometry.get());
    rtcAttachGeometryByID(target, geometry.get(), id);
    if (rtcGetDeviceError(device.get()) != RTC_ERROR_NONE) fail(device.get(), "geometry commit");
  }
};

Bvh::Bvh(const std::vector<Mesh>& meshes, const std::vector<SphereInput>& spheres,
         const HitFilter* sphere_filter, const std::vector<std::vector<Mesh>>& groups,
         const std::vector<InstanceInput>& instances,
         const std::vector<std::vector<SphereInput>>& sphere_poses)
    : impl_(std::make_unique<Impl>()) {
  impl_->device.reset(rtcNewDevice(nullptr));
  if (!impl_->device) throw std::runtime_error("Embree: rtcNewDevice failed");
  rtcSetDeviceErrorFunction(impl_->device.get(), log_device_error, nullptr);
  impl_->scene.reset(rtcNewScene(impl_->device.get()));
  if (!impl_->scene) fail(impl_->device.get(), "rtcNewScene");
  // Default (non-robust) traversal, as Embree's own tutorials use: robust mode costs ~30% of the
  // traversal time; ray origins are already offset past the hit point's error bound.
  for (uint32_t i = 0; i < meshes.size(); ++i) {
    if (!meshes[i].indices->empty()) impl_->add_mesh(meshes[i], i);
  }
  // Embree sizes its geometry table by the largest id: keep ids dense.
  if (!spheres.empty())
    impl_->add_spheres(spheres, sphere_poses, static_cast<uint32_t>(meshes.size()), sphere_filter);
  impl_->instance_base = static_cast<uint32_t>(meshes.size() + (spheres.empty() ? 0 : 1));
  if (!instances.empty()) {
    for (const std::vector<Mesh>& group : groups) impl_->add_group(group);
    for (uint32_t i = 0; i < instances.size(); ++i)
      impl_->add_instance(instances[i], impl_->instance_base + i);
  }
  const RTCBuildQuality quality =
      build_quality(impl_->world_boxes(meshes, spheres, sphere_poses, instances));
  rtcSetSceneBuildQuality(impl_->scene.get(), quality);
  commit_scene(impl_->scene.get(), quality);
  if (rtcGetDeviceError(impl_->device.get()) != RTC_ERROR_NONE) {
    fail(impl_->device.get(), "rtcCommitScene");
  }
}

Bvh::~Bvh() = default;

std::optional<RayHit> Bvh::intersect(const Ray& ray) const {
  RayHit hit;
  if (!intersect(ray, hit)) return std::nullopt;
  return hit;
}

bool Bvh::intersect(const Ray& ray, RayHit& hit) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  float t_scale = 1.f;
  if (!to_embree(ray, rh.ray, t_scale)) return false;  // nothing can be found from there
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene.get(), &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  // t_scale is 1 for nearly every ray, and x / 1 is x: no division on the way to the hit point.
  hit.t = t_scale == 1.f ? rh.ray.tfar : rh.ray.tfar / t_scale;
  if (rh.hit.instID[0] != RTC_INVALID_GEOMETRY_ID) {
    hit.inst = rh.hit.instID[0] - impl_->instance_base;
    hit.geom = rh.hit.geomID;  // the mesh within the group
  } else {
    hit.inst = kNoInstance;
    hit.geom = rh.hit.geomID == impl_->sphere_id ? kSphereGeometry : rh.hit.geomID;
  }
  hit.prim = rh.hit.primID;
  hit.u = rh.hit.u;
  hit.v = rh.hit.v;
  return true;
}

bool Bvh::occluded(const Ray& ray) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay r;
  float t_scale = 1.f;
  // A segment that cannot be traced counts as blocked: no light leaks through it.
  if (!to_embree(ray, r, t_scale)) return true;
  rtcOccluded1(impl_->scene.get(), &context, &r);
  // An occluded ray comes back with tfar = -inf.
  return r.tfar < 0.f;
}

}  // namespace rayfarm

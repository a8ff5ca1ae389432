// Shading normals: interpolated from vertex normals at the hit, and never letting light through
// or behind the geometric surface. Against an exact answer: a Lambertian quad whose shading normal
// is tilted by theta from its geometric one, under a uniform sky, reflects
// albedo * L * (1 + cos theta) / 2 - the cosine-weighted share of the shading hemisphere that
// lies above the geometric plane.
#include <gtest/gtest.h>

#include <cmath>

#include "renderer/camera.h"
#include "renderer/renderer.h"
#include "renderer/scene_data.h"

namespace rayfarm {
namespace {

/// A unit quad in the z = 0 plane facing -z (towards the camera), with every vertex normal
/// `normal` (empty: flat), filling the view of a camera on the -z axis.
Scene tilted_quad_scene(const Vec3& normal, bool with_normals) {
  Scene s;
  s.film = {8, 8};
  s.camera.eye = {0.f, 0.f, -2.f};
  s.camera.look_at = {0.f, 0.f, 0.f};
  // Narrow enough that every camera ray stays above the shading horizon at the steepest tilt
  // tested (85 degrees): within 3 degrees of the geometric normal.
  s.camera.fov_y_deg = 4.f;
  Material m;
  m.kind = DiffuseMaterial{Vec3(0.5f)};
  s.materials.push_back(m);
  TriangleMesh mesh;
  mesh.positions = {{-1, -1, 0}, {-1, 1, 0}, {1, 1, 0}, {1, -1, 0}};  // front face -z
  mesh.indices = {0, 1, 2, 0, 2, 3};
  mesh.materials = {0, 0};
  if (with_normals) mesh.normals.assign(4, normal);
  s.meshes.push_back(mesh);
  s.background = Vec3(1.f);
  s.render.max_depth = 1;
  s.render.integrator = IntegratorType::kNaive;
  return s;
}

TEST(ShadingNormalTest, ResolveInterpolatesTheVertexNormals) {
  Scene s = tilted_quad_scene({}, false);
  s.meshes[0].normals = {normalize(Vec3(0, 0, -1)), normalize(Vec3(1, 0, -1)),
                         normalize(Vec3(0, 1, -1)), normalize(Vec3(0, 0, -1))};
  const SceneData data(s);
  // A ray at the point with barycentrics (u, v) of the first triangle (vertices 0, 1, 2).
  const float u = 0.25f, v = 0.5f;
  const Vec3 p = s.meshes[0].positions[0] * (1 - u - v) + s.meshes[0].positions[1] * u +
                 s.meshes[0].positions[2] * v;
  const Ray ray{{p.x, p.y, -1.f}, {0.f, 0.f, 1.f}};
  const auto hit = data.bvh().intersect(ray);
  ASSERT_TRUE(hit);
  const SurfaceHit sh = data.resolve(ray, *hit);
  const Vec3 expected =
      normalize(s.meshes[0].normals[0] * (1 - hit->u - hit->v) + s.meshes[0].normals[1] * hit->u +
                s.meshes[0].normals[2] * hit->v);
  EXPECT_NEAR(sh.ns.x, expected.x, 1e-6f);
  EXPECT_NEAR(sh.ns.y, expected.y, 1e-6f);
  EXPECT_NEAR(sh.ns.z, expected.z, 1e-6f);
  EXPECT_EQ(sh.n, Vec3(0.f, 0.f, -1.f));
}

TEST(ShadingNormalTest, NormalsAgainstTheGeometricSideAreTurnedToIt) {
  // Vertex normals wound against the triangle still shade its front: ns lies on n's side.
  const SceneData data(tilted_quad_scene({0.f, 0.f, 1.f}, true));
  const Ray ray{{0.2f, 0.1f, -1.f}, {0.f, 0.f, 1.f}};
  const auto hit = data.bvh().intersect(ray);
  ASSERT_TRUE(hit);
  EXPECT_EQ(data.resolve(ray, *hit).ns, Vec3(0.f, 0.f, -1.f));
}

struct Estimate {
  double mean = 0.0, standard_error = 0.0;
};

Estimate render_mean(const Scene& scene, uint32_t spp) {
  RenderSettings settings = scene.render;
  settings.spp = spp;
  settings.seed = 3;
  settings.sampler = SamplerType::kIndependent;  // the standard error below needs independence
  Renderer renderer(scene, settings);
  const TileResult r = renderer.render({0, 0, scene.film.width, scene.film.height}, {0, spp});
  double sum = 0.0, sum_sq = 0.0;
  for (size_t p = 0; p < r.rect.pixel_count(); ++p) {
    sum += from_fixed(r.sum[p * 3]);
    sum_sq += from_fixed(r.sum_sq[p * 3]);
  }
  const double n = double(r.rect.pixel_count()) * spp;
  Estimate e;
  e.mean = sum / n;
  e.standard_error = std::sqrt(std::max(0.0, sum_sq / n - e.mean * e.mean) / (n - 1.0));
  return e;
}

TEST(ShadingNormalTest, TiltedNormalReflectsTheClippedCosineShareOfTheSky) {
  // Four tilts, one comparison each: 5 standard errors keep the chance of a false alarm below
  // 4 * 6e-7.
  for (double theta_deg : {0.0, 30.0, 60.0, 85.0}) {
    const double theta = theta_deg * 3.14159265358979323846 / 180.0;
    const Vec3 normal(static_cast<float>(std::sin(theta)), 0.f,
                      static_cast<float>(-std::cos(theta)));
    const Estimate e = render_mean(tilted_quad_scene(normal, true), 512);
    const double expected = 0.5 * (1.0 + std::cos(theta)) / 2.0;
    EXPECT_NEAR(e.mean, expected, 5.0 * e.standard_error + 1e-6)
        << "tilt " << theta_deg << " degrees, standard error " << e.standard_error;
    EXPECT_LT(e.standard_error, 0.01 * expected) << "too few samples for a meaningful test";
  }
}

TEST(ShadingNormalTest, FlatMeshesRenderExactlyAsBefore) {
  // A mesh without normals, and one whose every vertex normal is zero (no normal: flat), give the
  // same bits: the flat path does not change.
  Scene flat = tilted_quad_scene({}, false);
  Scene zeros = tilted_quad_scene(Vec3(0.f), true);
  for (Scene* s : {&flat, &zeros}) {
    s->render.integrator = IntegratorType::kMis;
    s->render.max_depth = 4;
  }
  RenderSettings settings = flat.render;
  settings.spp = 16;
  const TileResult a = Renderer(flat, settings).render({0, 0, 8, 8}, {0, 16});
  const TileResult b = Renderer(zeros, settings).render({0, 0, 8, 8}, {0, 16});
  EXPECT_EQ(a.sum, b.sum);
  EXPECT_EQ(a.sum_sq, b.sum_sq);
}

TEST(OrthographicCameraTest, RaysAreParallelAndCoverTheViewHeight) {
  Camera c;
  c.projection = Camera::Projection::kOrthographic;
  c.eye = {1.f, 2.f, -10.f};
  c.look_at = {1.f, 2.f, 0.f};
  c.view_height = 4.f;
  const CameraModel model(c, {200, 100});  // aspect 2: 8 units wide
  const Ray top_left = model.generate(0.f, 0.f, 0.5f, 0.5f);
  const Ray bottom_right = model.generate(200.f, 100.f, 0.5f, 0.5f);
  const Ray centre = model.generate(100.f, 50.f, 0.9f, 0.1f);  // the lens numbers play no part
  for (const Ray& r : {top_left, bottom_right, centre}) EXPECT_EQ(r.dir, Vec3(0.f, 0.f, 1.f));
  EXPECT_EQ(centre.org, c.eye);
  // Right is forward x up = +z x +y = -x; the top row is +y.
  EXPECT_NEAR(top_left.org.x, 1.f + 4.f, 1e-5f);
  EXPECT_NEAR(top_left.org.y, 2.f + 2.f, 1e-5f);
  EXPECT_NEAR(bottom_right.org.x, 1.f - 4.f, 1e-5f);
  EXPECT_NEAR(bottom_right.org.y, 2.f - 2.f, 1e-5f);
  EXPECT_EQ(top_left.org.z, -10.f);
}

}  // namespace
}  // namespace rayfarm

// Limits on submissions: the queue and the bundle's size before the master unpacks a bundle; the
// film's pixels and the spp (the scene's or the override), and tiles whose results would not fit
// in a message, checked by the scene parser before it loads any mesh. Each refusal names the
// limit, the value and the option that raises it.
#include <gtest/gtest.h>

#include "common/bundle/bundle.h"
#include "common/protocol/convert.h"
#include "master/peer_limits.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {

wire::SubmitJob job(const std::string& scene_text, std::string extra_file = "") {
  std::vector<BundleFile> files{{"scene.json", scene_text}};
  if (!extra_file.empty()) files.push_back({"mesh.obj", std::move(extra_file)});
  wire::SubmitJob request;
  protocol::bundle_to_wire(make_bundle(files), request.mutable_bundle());
  request.set_scene_path("scene.json");
  return request;
}

std::string scene(uint32_t width, uint32_t height, const std::string& render = "") {
  return "{\"film\": {\"width\": " + std::to_string(width) +
         ", \"height\": " + std::to_string(height) + "}" +
         (render.empty() ? "" : ", \"render\": " + render) +
         ", \"camera\": {\"eye\": [0, 0, -1], \"look_at\": [0, 0, 0], \"fov_y\": 40}, "
         "\"materials\": {\"m\": {\"type\": \"diffuse\"}}, "
         "\"shapes\": [{\"type\": \"mesh\", \"file\": \"missing.obj\", \"material\": \"m\"}]}";
}

/// What the master's check says of `request`: the scene parser runs it once it has read the film
/// and the render settings, before the mesh (missing here, so a scene that passes the check
/// fails on it instead).
std::optional<std::string> check_submission(const wire::SubmitJob& request, size_t jobs_waiting,
                                            const Limits& limits) {
  if (auto refusal = check_queue(jobs_waiting, limits)) return refusal;
  if (auto refusal = check_figures(bundle_figures(request), limits)) return refusal;
  testing::TempDir dir;
  const std::string& text = request.bundle().files(0).data();
  try {
    load_scene(dir.write("scene.json", text), scene_check(request, limits));
  } catch (const SceneRefused& e) {
    return e.what();
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.obj"), std::string::npos) << e.what();
  }
  return std::nullopt;
}

TEST(Limits, FiguresComeFromTheSceneAndTheOverrides) {
  RenderSettings render;
  render.spp = 300;
  const SubmissionFigures f =
      figures_of(job(scene(640, 480, "{\"spp\": 300}"), "v 0 0 0\n"), {640, 480}, render);
  EXPECT_EQ(f.width, std::optional<uint64_t>(640));
  EXPECT_EQ(f.height, std::optional<uint64_t>(480));
  EXPECT_EQ(f.spp, std::optional<uint64_t>(300));
  EXPECT_EQ(f.bundle_bytes, scene(640, 480, "{\"spp\": 300}").size() + 8);
  EXPECT_EQ(f.tile_size, 64u);

  wire::SubmitJob overridden = job(scene(640, 480, "{\"spp\": 300}"));
  overridden.mutable_overrides()->set_spp(7);
  overridden.mutable_overrides()->set_tile_size(16);
  overridden.mutable_overrides()->set_width(32);
  overridden.mutable_overrides()->set_height(24);
  const SubmissionFigures o = figures_of(overridden, {640, 480}, render);
  EXPECT_EQ(o.spp, std::optional<uint64_t>(7));
  EXPECT_EQ(o.tile_size, 16u);
  EXPECT_EQ(o.width, std::optional<uint64_t>(32));
  EXPECT_EQ(o.height, std::optional<uint64_t>(24));

  // Before the scene is read, only the bundle's figures are known.
  EXPECT_FALSE(bundle_figures(overridden).width);
  EXPECT_FALSE(bundle_figures(overridden).spp);
}

TEST(Limits, TheParserChecksTheLimitsBeforeItLoadsAMesh) {
  Limits limits;
  limits.max_image_pixels = 100;
  // No render block: the scene format's default spp; comments are allowed.
  wire::SubmitJob request = job("// a comment\n" + scene(8, 8));
  EXPECT_EQ(check_submission(request, 0, limits), std::nullopt);  // the mesh is what fails
  limits.max_spp = 63;
  const auto spp = check_submission(request, 0, limits);
  ASSERT_TRUE(spp);
  EXPECT_NE(spp->find("64 samples per pixel"), std::string::npos) << *spp;
  // A scene the parser refuses is refused for that, whatever the limits.
  testing::TempDir dir;
  EXPECT_THROW(load_scene(dir.write("scene.json", "not json"), scene_check(request, limits)),
               SceneError);
}

TEST(Limits, EachRefusalNamesTheLimitTheValueAndTheOption) {
  Limits limits;
  limits.max_image_pixels = 1000 * 1000;
  limits.max_spp = 1024;
  limits.max_bundle_bytes = 1000;
  limits.max_queued_jobs = 3;

  EXPECT_EQ(check_submission(job(scene(1000, 1000, "{\"spp\": 1024}")), 2, limits), std::nullopt);

  const auto big = check_submission(job(scene(1001, 1000)), 0, limits);
  ASSERT_TRUE(big);
  EXPECT_NE(big->find("1001x1000 = 1001000 pixels"), std::string::npos) << *big;
  EXPECT_NE(big->find("limit of 1000000 pixels (--max-image-pixels)"), std::string::npos) << *big;

  wire::SubmitJob many = job(scene(64, 64, "{\"spp\": 16}"));
  many.mutable_overrides()->set_spp(4096);
  const auto spp = check_submission(many, 0, limits);
  ASSERT_TRUE(spp);
  EXPECT_NE(spp->find("4096 samples per pixel"), std::string::npos) << *spp;
  EXPECT_NE(spp->find("1024 spp (--max-spp)"), std::string::npos) << *spp;
  EXPECT_TRUE(check_submission(job(scene(64, 64, "{\"spp\": 2048}")), 0, limits));

  const auto bundle = check_submission(job(scene(8, 8), std::string(2000, 'v')), 0, limits);
  ASSERT_TRUE(bundle);
  EXPECT_NE(bundle->find("(--max-bundle-mb)"), std::string::npos) << *bundle;
  EXPECT_NE(bundle->find("bytes)"), std::string::npos) << *bundle;

  const auto full = check_submission(job(scene(8, 8)), 3, limits);
  ASSERT_TRUE(full);
  EXPECT_NE(full->find("3 jobs are queued or running, the limit is 3 (--max-queued-jobs)"),
            std::string::npos)
      << *full;
}

TEST(Limits, ATileWhoseResultsWouldNotFitInAMessageIsRefused) {
  Limits limits;
  limits.max_message_bytes = 1 << 20;  // 1 MiB: about 96x96 pixels of sums at their largest
  wire::SubmitJob request = job(scene(4096, 4096));
  request.mutable_overrides()->set_tile_size(512);
  const auto refusal = check_submission(request, 0, limits);
  ASSERT_TRUE(refusal);
  EXPECT_NE(refusal->find("a tile of 512x512 pixels"), std::string::npos) << *refusal;
  EXPECT_NE(refusal->find("(--max-message-mb)"), std::string::npos) << *refusal;
  request.mutable_overrides()->set_tile_size(64);
  EXPECT_EQ(check_submission(request, 0, limits), std::nullopt);
  EXPECT_LE(unit_result_bytes(64, 64), uint64_t{1} << 20);
  // With the default limit (1 GiB), tiles up to 2048 pixels fit.
  EXPECT_LE(unit_result_bytes(2048, 2048), uint64_t(Limits{}.max_message_bytes));
}

}  // namespace
}  // namespace rayfarm::master

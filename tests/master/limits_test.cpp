// Limits on submissions, checked before the master loads a scene: the queue, the bundle's size,
// the film's pixels and the spp (the scene's or the override), and tiles whose results would not
// fit in a message. Each refusal names the limit, the value and the option that raises it.
#include <gtest/gtest.h>

#include "common/bundle/bundle.h"
#include "common/protocol/convert.h"
#include "master/limits.h"

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
         (render.empty() ? "" : ", \"render\": " + render) + ", \"camera\": {}}";
}

TEST(Limits, FiguresComeFromTheSceneAndTheOverrides) {
  const SubmissionFigures f = figures_of(job(scene(640, 480, "{\"spp\": 300}"), "v 0 0 0\n"));
  EXPECT_EQ(f.width, std::optional<uint64_t>(640));
  EXPECT_EQ(f.height, std::optional<uint64_t>(480));
  EXPECT_EQ(f.spp, std::optional<uint64_t>(300));
  EXPECT_EQ(f.bundle_bytes, scene(640, 480, "{\"spp\": 300}").size() + 8);
  EXPECT_EQ(f.tile_size, 64u);

  wire::SubmitJob overridden = job(scene(640, 480, "{\"spp\": 300}"));
  overridden.mutable_overrides()->set_spp(7);
  overridden.mutable_overrides()->set_tile_size(16);
  EXPECT_EQ(figures_of(overridden).spp, std::optional<uint64_t>(7));
  EXPECT_EQ(figures_of(overridden).tile_size, 16u);

  // No render block: the scene format's default spp. Comments are allowed, as in the parser.
  EXPECT_EQ(figures_of(job("// a comment\n" + scene(8, 8))).spp, std::optional<uint64_t>(64));
  // What the parser will refuse anyway is left to it: no figure, no refusal here.
  const SubmissionFigures bad = figures_of(job("{\"film\": {\"width\": -3, \"height\": \"x\"}"));
  EXPECT_FALSE(bad.width);
  EXPECT_FALSE(bad.height);
  EXPECT_FALSE(figures_of(job("not json")).width);
  EXPECT_FALSE(figures_of(job(std::string(200, '[') + std::string(200, ']'))).width);
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
  limits.max_message_bytes = 1 << 20;  // 1 MiB: about 100x100 pixels of sums
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

// Animated scenes through the CLI, with real processes on loopback and CURVE keys: `rayfarm render
// --frames` writes one image per frame and checks the whole range before the first, and a farm
// job of one frame (`submit --frame N`) renders that frame bit for bit as `rayfarm render --frame
// N` does. Every wait is bounded; every process is killed by PID at the end.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "common/net/keys.h"
#include "tests/e2e/farm_fixture.h"

namespace rayfarm::test {
namespace {

class FramesTest : public FarmFixture {
 protected:
  void SetUp() override {
    FarmFixture::SetUp();
    make_keys(keys(), {{"cli", "clients"}, {"w1", "workers"}});
    client_keys_ = net::read_key_pair(keys() / "own" / "cli.key_secret");
    master_public_ = net::read_key_pair(keys() / "master.key_secret").public_key;
  }
  fs::path keys() const { return dir() / "keys"; }
  std::vector<std::string> client_auth() const override {
    return {"--key", (keys() / "own" / "cli.key_secret").string(), "--master-key",
            (keys() / "master.key").string()};
  }
  net::Curve client_curve() const override {
    return {client_keys_.public_key, client_keys_.secret_key, master_public_, ""};
  }
  void start_farm() {
    run_master("master.log",
               {"--heartbeat-ms", "200", "--liveness", "3", "--key",
                (keys() / "master.key_secret").string(), "--worker-keys",
                (keys() / "workers").string(), "--client-keys", (keys() / "clients").string()});
    run_worker("w1", {"--threads", "2", "--heartbeat-ms", "200", "--liveness", "3", "--key",
                      (keys() / "own" / "w1.key_secret").string(), "--master-key",
                      (keys() / "master.key").string()});
  }

 private:
  net::KeyPair client_keys_;
  std::string master_public_;
};

TEST_F(FramesTest, RenderWritesOneImagePerFrameAndChecksTheRangeFirst) {
  const fs::path scene = small_scene("animated-box", 16);
  const fs::path out = dir() / "seq";
  fs::create_directories(out);
  const RunResult r = cli({"render", scene.string(), "--frames", "10-14:2", "--spp", "2", "-o",
                           (out / "box.####.exr").string()},
                          false);
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* name : {"box.0010.exr", "box.0012.exr", "box.0014.exr", "box.0012.png"}) {
    EXPECT_TRUE(fs::exists(out / name)) << name;
  }
  EXPECT_FALSE(fs::exists(out / "box.0011.exr"));
  EXPECT_NE(r.out.find("rendered 3 frames (10-14:2)"), std::string::npos) << r.out;
  // Frames change: the light fades in between frames 10 and 12.
  EXPECT_FALSE(bit_identical(out / "box.0010.exr", out / "box.0012.exr"));

  // Refused before anything renders: a range beyond the animation, a reversed one, a reference.
  const fs::path refused = dir() / "refused";
  fs::create_directories(refused);
  const auto expect_refused = [&](std::vector<std::string> extra, const std::string& words) {
    std::vector<std::string> args{"render", scene.string(), "--spp",
                                  "1",      "-o",           (refused / "x.exr").string()};
    args.insert(args.end(), extra.begin(), extra.end());
    const RunResult bad = cli(args, false);
    EXPECT_EQ(bad.code, 1) << bad.err;
    EXPECT_NE(bad.err.find(words), std::string::npos) << bad.err;
  };
  expect_refused({"--frames", "40-60"},
                 "--frames 40-60: beyond the scene's animation, frames 1-48");
  expect_refused({"--frames", "9-3"}, "reversed");
  expect_refused({"--frames", "1-3", "--reference", scene.string()}, "--reference is one image");
  expect_refused({"--frame", "49"}, "frame 49 is outside the scene's frames 1-48");
  const fs::path still = small_scene("furnace", 8);
  const RunResult on_still =
      cli({"render", still.string(), "--frames", "1-2", "-o", (refused / "x.exr").string()}, false);
  EXPECT_EQ(on_still.code, 1);
  EXPECT_NE(on_still.err.find("is a still scene"), std::string::npos) << on_still.err;
  EXPECT_TRUE(fs::is_empty(refused));
}

TEST_F(FramesTest, AFarmJobOfOneFrameEqualsTheLocalRenderOfThatFrame) {
  start_farm();
  const fs::path scene = small_scene("animated-box", 24);
  const std::vector<std::string> settings{"--spp", "4", "--seed", "7"};
  std::vector<std::string> at_frame = settings;
  at_frame.insert(at_frame.end(), {"--frame", "20"});
  const std::string job = submit(scene, at_frame);
  wait_for_state(job, wire::JOB_DONE);
  const auto shown = nlohmann::json::parse(cli({"status", job, "--json"}).out);
  EXPECT_EQ(shown["frame"], 20);
  EXPECT_NE(shown["name"].get<std::string>().find("frame 20"), std::string::npos) << shown;
  const fs::path farm = fetch(job);
  EXPECT_TRUE(bit_identical(farm, local_render(scene, at_frame)));
  EXPECT_FALSE(bit_identical(farm, local_render(scene, settings)));  // not the first frame

  // Without --frame an animated scene renders its first frame, and says so.
  const std::string first = submit(scene, settings);
  wait_for_state(first, wire::JOB_DONE);
  EXPECT_EQ(nlohmann::json::parse(cli({"status", first, "--json"}).out)["frame"], 1);
  EXPECT_TRUE(bit_identical(fetch(first), local_render(scene, settings)));

  // Frames the scene does not have are refused at submission, naming the cause.
  const RunResult beyond = cli({"submit", scene.string(), "--frame", "300"});
  EXPECT_EQ(beyond.code, 1);
  EXPECT_NE(beyond.err.find("frame 300 is outside the scene's frames 1-48"), std::string::npos)
      << beyond.err;
  const RunResult still = cli({"submit", small_scene("furnace", 8).string(), "--frame", "2"});
  EXPECT_EQ(still.code, 1);
  EXPECT_NE(still.err.find("the scene is a still"), std::string::npos) << still.err;
  // A still job has no frame.
  const std::string plain = submit(small_scene("furnace", 8), settings);
  EXPECT_TRUE(nlohmann::json::parse(cli({"status", plain, "--json"}).out)["frame"].is_null());
}

}  // namespace
}  // namespace rayfarm::test

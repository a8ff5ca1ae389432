// Animated scenes through the CLI, with real processes on loopback and CURVE keys: `rayfarm render
// --frames` writes one image per frame and checks the whole range before the first, and a farm
// job of one frame (`submit --frame N`) renders that frame bit for bit as `rayfarm render --frame
// N` does; a sequence's frames, contact sheet and movie are fetched. Every wait is bounded; every
// process is killed by PID at the end.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/image/contact_sheet.h"
#include "common/image/decode_image.h"
#include "common/util/read_file.h"
#include "tests/e2e/farm_fixture.h"
#include "tests/support/gltf_builder.h"

namespace rayfarm::test {
namespace {

class FramesTest : public KeyedFarmFixture {
 protected:
  void start_farm() {
    std::vector<std::string> master{"--heartbeat-ms", "200", "--liveness", "3"};
    const auto master_keyed = master_keys();
    master.insert(master.end(), master_keyed.begin(), master_keyed.end());
    run_master("master.log", master);
    std::vector<std::string> worker{"--threads", "2", "--heartbeat-ms", "200", "--liveness", "3"};
    const auto worker_keyed = worker_keys();
    worker.insert(worker.end(), worker_keyed.begin(), worker_keyed.end());
    run_worker("w1", worker);
  }
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

// Motion blur on the farm: the worker poses the scene within the shutter as the CLI does, and
// each sample's time is its own number: the farm's frame is the local one bit for bit.
TEST_F(FramesTest, AMotionBlurredFrameOnTheFarmEqualsTheLocalRender) {
  start_farm();
  const fs::path scene = small_scene("animated-box", 24);
  const std::vector<std::string> sharp{"--spp", "4", "--seed", "7", "--frame", "20"};
  std::vector<std::string> blurred = sharp;
  blurred.insert(blurred.end(), {"--shutter", "-0.5,0.5", "--motion-steps", "3"});
  const std::string job = submit(scene, blurred);
  wait_for_state(job, wire::JOB_DONE);
  const auto shown = nlohmann::json::parse(cli({"status", job, "--json"}).out);
  EXPECT_EQ(shown["shutter"], nlohmann::json::array({-0.5, 0.5})) << shown;
  EXPECT_EQ(shown["motion_steps"], 3) << shown;
  const fs::path farm = fetch(job);
  EXPECT_TRUE(bit_identical(farm, local_render(scene, blurred)));
  EXPECT_FALSE(bit_identical(farm, local_render(scene, sharp)));  // the blur is there

  // An animated glTF file rendered through its named camera (`--camera`, which the CLI sends as
  // a small JSON scene naming the file and its frames) and a film override: the worker poses the
  // file at the frame's and the shutter's times as the CLI does.
  testing::GltfBuilder b;
  const int mesh = b.add_quad(-1);
  b.push("nodes", {{"mesh", mesh}});  // sliding before a glowing backdrop (still)
  const int glow = b.push("materials", {{"emissiveFactor", {1, 1, 1}}});
  b.push("cameras", {{"type", "perspective"},
                     {"perspective", {{"yfov", 0.8}, {"aspectRatio", 1.0}, {"znear", 0.1}}}});
  b.push("nodes", {{"camera", 0}, {"name", "cam"}, {"translation", {0.5, 0.5, 4}}});
  b.push("nodes",
         {{"mesh", b.add_quad(glow)}, {"translation", {-4, -4, -1}}, {"scale", {9, 9, 1}}});
  b.doc["scenes"] = {{{"nodes", {0, 1, 2}}}};
  b.doc["scene"] = 0;
  const int times = b.add_floats({0.f, 1.f}, "SCALAR");
  const int moves = b.add_floats({-1, 0, 0, 1, 0, 0}, "VEC3");
  b.push("animations",
         {{"samplers", {{{"input", times}, {"output", moves}}}},
          {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}}}}});
  const fs::path glb = dir() / "slide.glb";
  std::ofstream(glb, std::ios::binary) << b.glb();
  const std::vector<std::string> gltf_blurred{"--camera", "cam",   "--frame", "7",         "--res",
                                              "20x20",    "--spp", "4",       "--shutter", "0,3"};
  const std::string gltf_job = submit(glb, gltf_blurred);
  wait_for_state(gltf_job, wire::JOB_DONE);
  const fs::path gltf_farm = fetch(gltf_job);
  EXPECT_TRUE(bit_identical(gltf_farm, local_render(glb, gltf_blurred)));
  const std::vector<std::string> gltf_sharp{"--camera", "cam",   "--frame", "7",
                                            "--res",    "20x20", "--spp",   "4"};
  EXPECT_FALSE(bit_identical(gltf_farm, local_render(glb, gltf_sharp)));
  // The same frame sharp on the farm: posed at the frame's time as the file rendered directly.
  const std::string sharp_job = submit(glb, gltf_sharp);
  wait_for_state(sharp_job, wire::JOB_DONE);
  EXPECT_TRUE(bit_identical(fetch(sharp_job), local_render(glb, gltf_sharp)));

  // A frame the file does not have is refused naming the file the user gave.
  const RunResult beyond = cli({"submit", glb.string(), "--camera", "cam", "--frame", "99"});
  EXPECT_EQ(beyond.code, 1);
  EXPECT_NE(beyond.err.find("slide.glb: /animation/frames: frame 99 is outside the scene's "
                            "frames 1-25"),
            std::string::npos)
      << beyond.err;

  // A shutter that closes before it opens is refused by the CLI, naming the option.
  const RunResult bad = cli({"submit", scene.string(), "--shutter", "0.5,-0.5"});
  EXPECT_EQ(bad.code, 2);  // a usage error
  EXPECT_NE(bad.err.find("--shutter"), std::string::npos) << bad.err;
}

TEST_F(FramesTest, ASequenceRendersEveryFrameAsTheLocalRenderOfThatFrame) {
  start_farm();
  const fs::path scene = small_scene("animated-box", 16);
  const std::vector<std::string> settings{"--spp", "4", "--seed", "5"};
  std::vector<std::string> args = settings;
  args.insert(args.end(), {"--frames", "1-7:3", "--name", "shot"});
  const std::string seq = submit(scene, args);
  wait_for_state(seq, wire::JOB_DONE);

  const auto shown = nlohmann::json::parse(cli({"status", seq, "--json"}).out);
  EXPECT_EQ(shown["name"], "shot");
  EXPECT_EQ(shown["frames_total"], 3);
  EXPECT_EQ(shown["frames_done"], 3);
  EXPECT_EQ(shown["passes_done"], shown["passes_total"]);
  EXPECT_EQ(shown["spp_done"], 4);
  ASSERT_EQ(shown["frames"].size(), 3u) << shown;
  EXPECT_EQ(shown["frames"][1]["frame"], 4);
  EXPECT_EQ(shown["frames"][1]["job"], seq + ".0004");
  EXPECT_EQ(shown["frames"][1]["state"], "done");
  const auto frame_job = nlohmann::json::parse(cli({"status", seq + ".0004", "--json"}).out);
  EXPECT_EQ(frame_job["sequence"], seq);
  EXPECT_EQ(frame_job["frame"], 4);
  EXPECT_TRUE(has_line(cli({"list"}).out, seq, "3/3 fr"));
  // watch of a finished sequence: its last line, without a stop rule of its own.
  const RunResult watched = cli({"watch", seq, "--timeout", "30"});
  EXPECT_EQ(watched.code, 0) << watched.err;
  EXPECT_TRUE(has_line(watched.out, seq, "done")) << watched.out;
  EXPECT_EQ(watched.out.find("()"), std::string::npos) << watched.out;

  // Every frame, fetched at once, is the local render of that frame bit for bit.
  const fs::path out = dir() / "farm-frames";
  fs::create_directories(out);
  const RunResult all = cli({"fetch", seq, "--all", "-o", (out / "shot.####.exr").string()});
  ASSERT_EQ(all.code, 0) << all.err;
  for (int frame : {1, 4, 7}) {
    std::vector<std::string> local = settings;
    local.insert(local.end(), {"--frame", std::to_string(frame)});
    EXPECT_TRUE(
        bit_identical(out / fmt::format("shot.{:04d}.exr", frame), local_render(scene, local)))
        << "frame " << frame;
  }
  EXPECT_FALSE(fs::exists(out / "shot.0002.exr"));
  const RunResult one = cli({"fetch", seq, "--frame", "7", "-o", (out / "seven.exr").string()});
  ASSERT_EQ(one.code, 0) << one.err;
  EXPECT_TRUE(bit_identical(out / "seven.exr", out / "shot.0007.exr"));
  const RunResult whole = cli({"fetch", seq, "-o", (out / "whole.exr").string()});
  EXPECT_EQ(whole.code, 1);
  EXPECT_NE(whole.err.find("is a sequence of 3 frames: fetch one frame (--frame N), all of them "
                           "(--all), its contact sheet (-o NAME.png) or its movie (-o NAME.mp4)"),
            std::string::npos)
      << whole.err;
  EXPECT_FALSE(fs::exists(out / "whole.exr"));
  // Its previews: the contact sheet, and the movie that ffmpeg makes once every frame is done.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  std::string previews;
  while (std::chrono::steady_clock::now() < deadline) {
    previews = nlohmann::json::parse(cli({"status", seq, "--json"}).out)["previews"];
    if (previews != "contact sheet; movie being made") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_EQ(previews, "contact sheet; movie");
  const RunResult sheet = cli({"fetch", seq, "-o", (out / "sheet.png").string()});
  ASSERT_EQ(sheet.code, 0) << sheet.err;
  EXPECT_NE(sheet.out.find("the contact sheet of sequence " + seq), std::string::npos);
  const std::string png = read_whole_file(out / "sheet.png", 1 << 26);
  const DecodedImage decoded =
      decode_image({reinterpret_cast<const uint8_t*>(png.data()), png.size()}, "sheet.png");
  const SheetLayout layout = sheet_layout(3, 16, 16);
  EXPECT_EQ(decoded.width, layout.width());
  EXPECT_EQ(decoded.height, layout.height());
  const RunResult movie = cli({"fetch", seq, "-o", (out / "shot.mp4").string()});
  ASSERT_EQ(movie.code, 0) << movie.err;
  const std::string mp4 = read_whole_file(out / "shot.mp4", 1 << 26);
  ASSERT_GT(mp4.size(), 12u);
  EXPECT_EQ(mp4.substr(4, 4), "ftyp");  // an ISO media file
  const RunResult frame_movie =
      cli({"fetch", seq, "--frame", "4", "-o", (out / "four.mp4").string()});
  EXPECT_EQ(frame_movie.code, 1);
  EXPECT_NE(frame_movie.err.find("its movie is fetched without --frame or --all"),
            std::string::npos)
      << frame_movie.err;
  const RunResult still_movie = cli({"fetch", seq + ".0004", "-o", (out / "four.mp4").string()});
  EXPECT_EQ(still_movie.code, 1);
  EXPECT_NE(still_movie.err.find("is not a sequence: it has no movie"), std::string::npos)
      << still_movie.err;
  const RunResult missing = cli({"fetch", seq, "--frame", "2", "-o", (out / "two.exr").string()});
  EXPECT_EQ(missing.code, 1);
  EXPECT_NE(missing.err.find("has no frame 2"), std::string::npos) << missing.err;

  // A frame is removed with its sequence only; the sequence goes with every frame's folder.
  const RunResult frame_rm = cli({"rm", seq + ".0004"});
  EXPECT_EQ(frame_rm.code, 1);
  EXPECT_NE(frame_rm.err.find("remove the sequence"), std::string::npos) << frame_rm.err;
  ASSERT_EQ(cli({"rm", seq}).code, 0);
  EXPECT_EQ(cli({"status", seq}).code, 1);
  EXPECT_EQ(cli({"status", seq + ".0001"}).code, 1);

  // Refused before anything is sent: beyond the animation, on a still scene, with a reference.
  const RunResult beyond = cli({"submit", scene.string(), "--frames", "40-60"});
  EXPECT_EQ(beyond.code, 1);
  EXPECT_NE(beyond.err.find("beyond the scene's animation, frames 1-48"), std::string::npos)
      << beyond.err;
}

TEST_F(FramesTest, AListOfSceneFilesIsASequenceOfItsFiles) {
  // frame_0001.json .. frame_0003.json: the Cornell box seen from three places.
  const fs::path box = small_scene("cornell-box", 16);
  const nlohmann::json base = nlohmann::json::parse(read_file(box));
  const fs::path shots = dir() / "shots";
  fs::create_directories(shots);
  for (int frame = 1; frame <= 3; ++frame) {
    nlohmann::json scene = base;
    scene["camera"]["eye"][0] = 278 + 40 * frame;
    std::ofstream(shots / fmt::format("frame_{:04d}.json", frame)) << scene.dump(2);
  }
  const fs::path pattern = shots / "frame_####.json";
  const std::vector<std::string> settings{"--spp", "4", "--seed", "3"};
  const fs::path out = dir() / "list-out";
  fs::create_directories(out);
  std::vector<std::string> local{"render",    pattern.string(),
                                 "--frames",  "1-3",
                                 "-o",        (out / "local.####.exr").string(),
                                 "--threads", "2"};
  local.insert(local.end(), settings.begin(), settings.end());
  const RunResult rendered = cli(local, false);
  ASSERT_EQ(rendered.code, 0) << rendered.err;
  EXPECT_FALSE(bit_identical(out / "local.0001.exr", out / "local.0002.exr"));

  start_farm();
  std::vector<std::string> args = settings;
  args.insert(args.end(), {"--frames", "1-3", "--wait", "-o", (out / "farm.####.exr").string()});
  const std::string seq = submit(pattern, args);
  wait_for_state(seq, wire::JOB_DONE);
  for (int frame = 1; frame <= 3; ++frame) {
    EXPECT_TRUE(bit_identical(out / fmt::format("farm.{:04d}.exr", frame),
                              out / fmt::format("local.{:04d}.exr", frame)))
        << "frame " << frame;
  }
  // One frame of the list is the still scene in its file.
  const RunResult one = cli({"render", pattern.string(), "--frame", "2", "--spp", "4", "--seed",
                             "3", "-o", (out / "two.exr").string(), "--threads", "2"},
                            false);
  ASSERT_EQ(one.code, 0) << one.err;
  EXPECT_TRUE(bit_identical(out / "two.exr", out / "local.0002.exr"));

  // Refused before anything renders or is sent, naming the frame and the file.
  const auto expect_refused = [&](const std::string& command, std::vector<std::string> extra,
                                  const std::string& words, int code = 1) {
    std::vector<std::string> a{command, pattern.string(), "--spp", "1"};
    if (command == "render") a.insert(a.end(), {"-o", (out / "x.exr").string()});
    a.insert(a.end(), extra.begin(), extra.end());
    const RunResult bad = cli(a, command == "submit");
    EXPECT_EQ(bad.code, code) << command << ": " << bad.err;
    EXPECT_NE(bad.err.find(words), std::string::npos) << bad.err;
  };
  for (const char* command : {"render", "submit"}) {
    expect_refused(command, {"--frames", "1-4"},
                   "--frames 1-4: frame 4's scene " + (shots / "frame_0004.json").string() +
                       " does not exist");
    // No frames named for a list: a missing argument, a usage error (docs/cli.md).
    expect_refused(command, {}, "is a list of scene files, one per frame", 2);
  }
  nlohmann::json wide = base;
  wide["film"] = {{"width", 32}, {"height", 16}};
  std::ofstream(shots / "frame_0004.json") << wide.dump(2);
  expect_refused("submit", {"--frames", "1-4"},
                 (shots / "frame_0004.json").string() + " is 32x16 but " +
                     (shots / "frame_0001.json").string() +
                     " is 16x16: the frames of a sequence share one film");
  std::ofstream(shots / "frame_0005.json") << read_file(small_scene("animated-box", 16));
  expect_refused("render", {"--frames", "5-5"},
                 "is animated: the files of a list are still scenes");
}

TEST_F(FramesTest, ASequenceIsCancelledPausedAndRetriedAsOne) {
  start_farm();
  const fs::path scene = small_scene("animated-box", 32);
  const std::string seq = submit(scene, {"--spp", "256", "--frames", "1-48", "--paused"});
  wire::JobStatus st = status(seq);
  EXPECT_EQ(st.state(), wire::JOB_QUEUED);
  EXPECT_TRUE(st.paused());
  EXPECT_EQ(st.frames_total(), 48u);
  EXPECT_EQ(st.units_leased(), 0u);
  const RunResult priority = cli({"set-priority", seq, "-3"});
  ASSERT_EQ(priority.code, 0) << priority.err;
  EXPECT_EQ(nlohmann::json::parse(cli({"status", seq + ".0030", "--json"}).out)["priority"], -3);
  ASSERT_EQ(cli({"resume", seq}).code, 0);
  wait_for_units(seq, 1);
  const RunResult cancel = cli({"cancel", seq});
  ASSERT_EQ(cancel.code, 0) << cancel.err;
  wait_for_state(seq, wire::JOB_CANCELLED);
  st = status(seq);
  EXPECT_LT(st.frames_done(), 48u);
  for (const auto& f : st.frames()) {
    EXPECT_TRUE(f.state() == wire::JOB_CANCELLED || f.state() == wire::JOB_DONE) << f.frame();
  }
  // Retried, the cancelled frames are queued again (and cancelled again here).
  const RunResult retry = cli({"retry", seq});
  ASSERT_EQ(retry.code, 0) << retry.err;
  EXPECT_NE(status(seq).state(), wire::JOB_CANCELLED);
  ASSERT_EQ(cli({"cancel", seq}).code, 0);
  wait_for_state(seq, wire::JOB_CANCELLED);
  ASSERT_EQ(cli({"rm", seq}).code, 0) << cli({"rm", seq}).err;
}

}  // namespace
}  // namespace rayfarm::test

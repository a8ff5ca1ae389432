// The rayfarm CLI as people and scripts use it, with real processes on loopback: outputs checked
// before any work, usage errors with a suggestion and exit code 2, --version, shell completion,
// --res, --json on every listing command, watch riding out a master restart (and a master that
// hangs up handshakes while it is not listening yet), and the workers, rm and retry commands.
// Every process uses CURVE keys; every wait is bounded; every process is killed by PID at the end.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/image/exr.h"
#include "common/net/keys.h"
#include "common/protocol/version.h"
#include "tests/e2e/farm_fixture.h"
#include "tests/support/gltf_builder.h"
#include "tests/support/read_png.h"

namespace rayfarm::test {
namespace {
using nlohmann::json;

/// The JSON objects of `text`, one a line; a line that does not parse fails the test.
std::vector<json> json_lines(const std::string& text) {
  std::vector<json> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.empty()) continue;
    try {
      out.push_back(json::parse(line));
    } catch (const std::exception& e) {
      ADD_FAILURE() << "not a JSON line: " << line << " (" << e.what() << ")";
    }
  }
  return out;
}

class CliTest : public KeyedFarmFixture {
 protected:
  void start_master(const std::string& log = "master.log") {
    std::vector<std::string> options{"--heartbeat-ms", "200", "--liveness", "3",
                                     "--image-interval-ms", "500",
                                     // The farm's operator: may remove a record nobody can be
                                     // shown to own.
                                     "--admin-clients", "cli"};
    const auto with_keys = master_keys();
    options.insert(options.end(), with_keys.begin(), with_keys.end());
    run_master(log, options);
  }
  Process& start_worker() {
    std::vector<std::string> options{"--threads",  "1", "--heartbeat-ms",     "200",
                                     "--liveness", "3", "--reconnect-max-ms", "500"};
    const auto with_keys = worker_keys();
    options.insert(options.end(), with_keys.begin(), with_keys.end());
    return run_worker("w1", options);
  }
  /// The CLI started in the background (farm options added), for commands that outlive a step.
  std::unique_ptr<Process> cli_in_background(std::vector<std::string> args, const std::string& name) {
    std::vector<std::string> argv{bin("cli/rayfarm")};
    argv.insert(argv.end(), args.begin(), args.end());
    argv.insert(argv.end(), {"--master", client_endpoint()});
    const auto auth = client_auth();
    argv.insert(argv.end(), auth.begin(), auth.end());
    return std::make_unique<Process>(argv, dir() / (name + ".out"), dir() / (name + ".err"));
  }
  RunResult finish(Process& p, const std::string& name, milliseconds timeout) {
    RunResult r;
    r.code = p.wait(timeout).value_or(-1);
    r.out = read_file(dir() / (name + ".out"));
    r.err = read_file(dir() / (name + ".err"));
    return r;
  }
};

// --- Without a farm ---

TEST_F(CliTest, RenderChecksItsOutputBeforeRenderingAndItsExtensionChoosesTheFormat) {
  const fs::path scene = small_scene("furnace", 16);
  // A folder that does not exist, an extension that is neither .exr nor .png: refused at once,
  // naming the path, and nothing is rendered ("time" is the figures' line after a render).
  for (const auto& [output, cause] :
       {std::pair<std::string, std::string>{"/nonexistent/dir/x.exr", "/nonexistent/dir"},
        {(dir() / "x.jpg").string(), ".exr"}}) {
    const RunResult r = cli({"render", scene.string(), "-o", output, "--spp", "4"}, false);
    EXPECT_EQ(r.code, 1) << output;
    EXPECT_NE(r.err.find(output), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(cause), std::string::npos) << r.err;
    EXPECT_EQ(r.out.find("time "), std::string::npos) << r.out;
  }
  EXPECT_FALSE(fs::exists(dir() / "x.jpg"));
  // x.png: the preview alone, not overwritten by another file of the same name.
  const RunResult png = cli({"render", scene.string(), "-o", (dir() / "p.png").string(), "--spp",
                             "4"},
                            false);
  ASSERT_EQ(png.code, 0) << png.err;
  EXPECT_NE(png.out.find("wrote " + (dir() / "p.png").string() + "\n"), std::string::npos)
      << png.out;
  EXPECT_FALSE(fs::exists(dir() / "p.exr"));
  // A picture was asked for: no error record beside it unless asked for.
  EXPECT_FALSE(fs::exists(dir() / "p.error.csv"));
  EXPECT_FALSE(fs::exists(dir() / "p.error.png"));
  const RunResult recorded = cli({"render", scene.string(), "-o", (dir() / "q.png").string(),
                                  "--spp", "4", "--error-record"},
                                 false);
  ASSERT_EQ(recorded.code, 0) << recorded.err;
  EXPECT_TRUE(fs::exists(dir() / "q.error.csv"));
  EXPECT_TRUE(fs::exists(dir() / "q.error.png"));
  EXPECT_EQ(testing::read_png_rgb8(dir() / "p.png").width, 16u);
  // x.exr: the EXR and its preview.
  const RunResult exr = cli({"render", scene.string(), "-o", (dir() / "e.exr").string(), "--spp",
                             "4"},
                            false);
  ASSERT_EQ(exr.code, 0) << exr.err;
  EXPECT_EQ(read_exr(dir() / "e.exr").width, 16u);
  EXPECT_EQ(testing::read_png_rgb8(dir() / "e.png").width, 16u);
  EXPECT_NE(exr.err.find(protocol::kBuildVersion), std::string::npos) << exr.err;
  // Its error record as JSON lines: a row per line, as in the CSV.
  const RunResult report = cli({"report", (dir() / "e.error.csv").string(), "--json"}, false);
  ASSERT_EQ(report.code, 0) << report.err;
  const auto rows = json_lines(report.out);
  ASSERT_FALSE(rows.empty());
  EXPECT_EQ(rows.size() + 1, count_of(read_file(dir() / "e.error.csv"), "\n"));
  for (const json& row : rows) {
    EXPECT_TRUE(row.at("spp").is_number());
    EXPECT_TRUE(row.at("ref_rel_mse").is_null()) << "no reference";
  }
  EXPECT_TRUE(rows.back().at("est_rel_mse").is_number()) << report.out;
}

TEST_F(CliTest, UsageErrorsExit2WithTheUsageLineAndANearMiss) {
  const fs::path scene = small_scene("furnace", 16);
  struct Case {
    std::vector<std::string> args;
    std::string suggestion, usage;
  };
  for (const Case& c : {Case{{"sumbit", scene.string()}, "did you mean 'submit'?", "Usage: rayfarm"},
                        Case{{"submit", scene.string(), "--sp", "4"}, "did you mean '--spp'?",
                             "Usage: rayfarm submit"},
                        Case{{"render", scene.string(), "-o", "x.exr", "--intgrator", "mis"},
                             "did you mean '--integrator'?", "Usage: rayfarm render"},
                        Case{{"list", "--frobnicate"}, "", "Usage: rayfarm list"}}) {
    const RunResult r = cli(c.args, false);
    EXPECT_EQ(r.code, 2) << c.args[0] << ": " << r.err;
    if (!c.suggestion.empty()) {
      EXPECT_NE(r.err.find(c.suggestion), std::string::npos) << r.err;
    } else {
      EXPECT_EQ(r.err.find("did you mean"), std::string::npos) << r.err;
    }
    EXPECT_NE(r.err.find(c.usage), std::string::npos) << r.err;
  }
  const RunResult unknown = cli({"frobnicate"}, false);
  EXPECT_EQ(unknown.code, 2);
  EXPECT_NE(unknown.err.find("unknown command 'frobnicate'"), std::string::npos) << unknown.err;

  const RunResult version = cli({"--version"}, false);
  EXPECT_EQ(version.code, 0);
  EXPECT_EQ(version.out, std::string(protocol::kBuildVersion) + "\n");
  for (const std::string program : {"master/rayfarm-master", "worker/rayfarm-worker"}) {
    const fs::path out = dir() / (fs::path(program).filename().string() + ".version");
    Process p({bin(program), "--version"}, out, out);
    EXPECT_EQ(p.wait(milliseconds{20000}), std::optional<int>(0));
    EXPECT_EQ(read_file(out), std::string(protocol::kBuildVersion) + "\n") << program;
  }
}

// docs/cli.md's table of exit codes, walked without a farm: 1 for an error named on stderr
// (compare's unreadable image among them, as cmp's), 2 for every malformed or misplaced option
// (--res as --max-depth, -D on a JSON scene, --res with --width), 3 for a master that cannot be
// reached. (4 and 5 need a farm: farm_e2e_test.cpp and the watch tests.)
TEST_F(CliTest, EveryExitCodeIsTheOneDocsCliMdGives) {
  const fs::path scene = small_scene("furnace", 16);
  const std::string out = (dir() / "x.exr").string();
  struct Case {
    std::vector<std::string> args;
    int code;
    std::string says;
  };
  const std::vector<Case> cases{
      {{"render", scene.string(), "-o", out, "--res", "12"}, 2, "--res"},
      {{"render", scene.string(), "-o", out, "--res", "0x5"}, 2, "--res"},
      {{"render", scene.string(), "-o", out, "--res", "16x16", "--width", "8"}, 2, "--width"},
      {{"render", scene.string(), "-o", out, "--width", "0"}, 2, "--width"},
      {{"render", scene.string(), "-o", out, "--max-depth", "abc"}, 2, "--max-depth"},
      {{"render", scene.string(), "-o", out, "-D", "x=1"}, 2, "-D"},
      {{"submit", scene.string(), "-o", out}, 2, "--wait"},
      {{"compare", (dir() / "missing.exr").string(), (dir() / "other.exr").string()},
       1,
       "missing.exr"},
      {{"render", (dir() / "no-such-scene.json").string(), "-o", out, "--spp", "1"},
       1,
       "no-such-scene.json"},
      {{"status", "--detail"}, 2, "--detail"},
      {{"drain"}, 2, "worker"},
      {{"enable", "w1", "--nonsense"}, 2, "--nonsense"},
  };
  for (const Case& c : cases) {
    const RunResult r = cli(c.args, false);
    std::string line;
    for (const auto& a : c.args) line += a + " ";
    EXPECT_EQ(r.code, c.code) << line << "\n" << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << line << "\n" << r.err;
    if (c.code == 2) EXPECT_NE(r.err.find("Usage: rayfarm"), std::string::npos) << r.err;
    EXPECT_TRUE(r.out.empty()) << line << "\n" << r.out;
  }
  EXPECT_FALSE(fs::exists(out)) << "no case renders";
  // No master listens at the fixture's endpoint: 3, within the timeout.
  const RunResult unreachable = cli({"status", "j0001", "--timeout", "1"});
  EXPECT_EQ(unreachable.code, 3) << unreachable.err;
  EXPECT_NE(unreachable.err.find("cannot reach master"), std::string::npos) << unreachable.err;
}

TEST_F(CliTest, BashCompletionIsValidBashAndKnowsEveryCommandAndItsOptions) {
  const RunResult r = cli({"completion", "bash"}, false);
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* word : {"submit", "watch", "workers", "retry", "--spp", "--json", "--res",
                           "--target-error", "complete -o filenames"}) {
    EXPECT_NE(r.out.find(word), std::string::npos) << word;
  }
  std::ofstream(dir() / "rayfarm.bash") << r.out;
  // bash parses it, and completing "rayfarm sub" and "rayfarm submit --sp" gives the near words.
  std::ofstream(dir() / "try.sh")
      << "source " << (dir() / "rayfarm.bash").string() << "\n"
      << "COMP_WORDS=(rayfarm sub); COMP_CWORD=1; _rayfarm; echo \"${COMPREPLY[*]}\"\n"
      << "COMP_WORDS=(rayfarm submit --sp); COMP_CWORD=2; _rayfarm; echo \"${COMPREPLY[*]}\"\n";
  Process bash({"/bin/bash", (dir() / "try.sh").string()}, dir() / "try.out", dir() / "try.err");
  ASSERT_EQ(bash.wait(milliseconds{20000}), std::optional<int>(0)) << read_file(dir() / "try.err");
  EXPECT_EQ(read_file(dir() / "try.out"), "submit\n--spp\n") << read_file(dir() / "try.err");
}

TEST_F(CliTest, LocalClusterHelpPrintsItsUsageNotItsCode) {
  const std::string script = (fs::path(RAYFARM_SOURCE_DIR) / "deploy" / "local-cluster").string();
  Process help({"/bin/bash", script, "--help"}, dir() / "help.out", dir() / "help.err");
  ASSERT_EQ(help.wait(milliseconds{20000}), std::optional<int>(0)) << read_file(dir() / "help.err");
  const std::string out = read_file(dir() / "help.out");
  EXPECT_NE(out.find("deploy/local-cluster start [--workers N]"), std::string::npos) << out;
  EXPECT_NE(out.find("source .cluster/env"), std::string::npos) << out;
  for (const char* code : {"set -euo", "repo_root=", "#"}) {
    EXPECT_EQ(out.find(code), std::string::npos) << code << " in:\n" << out;
  }
}

TEST_F(CliTest, ResOverridesTheFilmLocallyAndOnTheFarmAlike) {
  const fs::path scene = small_scene("cornell-box", 32);
  const RunResult bad = cli({"render", scene.string(), "-o", (dir() / "b.exr").string(), "--res",
                             "24by16"},
                            false);
  EXPECT_EQ(bad.code, 2) << "a malformed option is a usage error";
  EXPECT_NE(bad.err.find("--res: expected WIDTHxHEIGHT"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("'24by16'"), std::string::npos) << bad.err;
  const std::vector<std::string> settings{"--spp", "8", "--seed", "3", "--res", "24x16"};
  const fs::path local = local_render(scene, settings);
  EXPECT_EQ(read_exr(local).width, 24u);
  EXPECT_EQ(read_exr(local).height, 16u);

  start_master();
  start_worker();
  // --wait -o: a bad output is refused before the job is sent.
  const RunResult refused = cli({"submit", scene.string(), "--wait", "-o", "/nonexistent/x.exr"});
  EXPECT_EQ(refused.code, 1);
  EXPECT_NE(refused.err.find("/nonexistent"), std::string::npos) << refused.err;
  EXPECT_EQ(cli({"list"}).out, "no jobs\n");
  // The farm renders the same film as the local render, and --wait -o fetches it.
  std::vector<std::string> args{"submit", scene.string(), "--wait", "-o",
                                (dir() / "farm.exr").string()};
  args.insert(args.end(), settings.begin(), settings.end());
  const RunResult r = cli(args);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("wrote " + (dir() / "farm.exr").string()), std::string::npos) << r.err;
  EXPECT_TRUE(bit_identical(dir() / "farm.exr", local));
}

TEST_F(CliTest, AGlbRendersThroughTheNamedCameraLocallyAndOnTheFarmAlike) {
  // An emissive quad seen by two cameras: "near" (the first) and "far".
  testing::GltfBuilder b;
  const int lamp =
      b.push("materials", {{"name", "lamp"},
                           {"emissiveFactor", {1.0, 0.5, 0.25}},
                           {"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5, 0.5, 1}}}}});
  b.push("nodes", {{"mesh", b.add_quad(lamp)}, {"translation", {-0.5, -0.5, 0}}});
  b.push("cameras", {{"name", "near"},
                     {"type", "perspective"},
                     {"perspective", {{"yfov", 0.5}, {"znear", 0.1}}}});
  b.push(
      "cameras",
      {{"name", "far"}, {"type", "perspective"}, {"perspective", {{"yfov", 0.5}, {"znear", 0.1}}}});
  b.push("nodes", {{"camera", 0}, {"translation", {0, 0, 2}}});
  b.push("nodes", {{"camera", 1}, {"translation", {0, 0, 6}}});
  const fs::path glb = dir() / "model" / "lamp.glb";
  fs::create_directories(glb.parent_path());
  std::ofstream(glb, std::ios::binary) << b.glb();

  const std::vector<std::string> settings{"--spp", "4", "--res", "24x16"};
  const fs::path near = local_render(glb, settings);
  std::vector<std::string> far_settings = settings;
  far_settings.insert(far_settings.end(), {"--camera", "far"});
  const fs::path far = local_render(glb, far_settings);
  EXPECT_FALSE(bit_identical(near, far));  // the camera changed the view
  const RunResult unknown =
      cli({"render", glb.string(), "-o", (dir() / "x.exr").string(), "--camera", "side"}, false);
  EXPECT_EQ(unknown.code, 1);
  EXPECT_NE(unknown.err.find("no camera named \"side\""), std::string::npos) << unknown.err;

  start_master();
  start_worker();
  std::vector<std::string> args{"submit", glb.string(), "--wait", "-o",
                                (dir() / "farm.exr").string()};
  args.insert(args.end(), far_settings.begin(), far_settings.end());
  const RunResult r = cli(args);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(bit_identical(dir() / "farm.exr", far));
}

// A glTF file without light renders black with a warning that says so; --environment uniform
// lights it, locally and on the farm alike, and is a usage error where it does not apply.
TEST_F(CliTest, AGlbWithoutLightIsWarnedAboutAndLitByEnvironment) {
  testing::GltfBuilder b;
  const int grey =
      b.push("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5, 0.5, 1}}}}});
  b.push("nodes", {{"mesh", b.add_quad(grey)}, {"translation", {-0.5, -0.5, 0}}});
  b.push("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 0.5}, {"znear", 0.1}}}});
  b.push("nodes", {{"camera", 0}, {"translation", {0, 0, 3}}});
  const fs::path glb = dir() / "dark" / "quad.glb";
  fs::create_directories(glb.parent_path());
  std::ofstream(glb, std::ios::binary) << b.glb();
  const std::vector<std::string> settings{"--spp", "4", "--res", "16x16"};

  const RunResult dark = cli(
      {"render", glb.string(), "-o", (dir() / "dark.exr").string(), "--spp", "4", "--res", "16x16"},
      false);
  ASSERT_EQ(dark.code, 0) << dark.err;
  EXPECT_NE(dark.err.find("the scene has no light"), std::string::npos) << dark.err;

  std::vector<std::string> lit_settings = settings;
  lit_settings.insert(lit_settings.end(), {"--environment", "uniform"});
  const RunResult lit = cli({"render", glb.string(), "-o", (dir() / "lit.exr").string(), "--spp",
                             "4", "--res", "16x16", "--environment", "uniform"},
                            false);
  ASSERT_EQ(lit.code, 0) << lit.err;
  EXPECT_EQ(lit.err.find("the scene has no light"), std::string::npos) << lit.err;
  const fs::path local = local_render(glb, lit_settings);
  EXPECT_FALSE(bit_identical(local, dir() / "dark.exr"));

  // Not a glTF file, or an image outside the file's folder: usage errors.
  const RunResult json = cli(
      {"render", (fs::path(RAYFARM_SOURCE_DIR) / "scenes" / "cornell-box" / "scene.json").string(),
       "-o", (dir() / "x.exr").string(), "--environment", "uniform"},
      false);
  EXPECT_EQ(json.code, 2) << json.err;
  EXPECT_NE(json.err.find("--environment lights a glTF file"), std::string::npos) << json.err;
  std::ofstream(dir() / "outside.hdr") << "not read";
  const RunResult outside = cli({"render", glb.string(), "-o", (dir() / "x.exr").string(),
                                 "--environment", (dir() / "outside.hdr").string()},
                                false);
  EXPECT_EQ(outside.code, 2) << outside.err;
  EXPECT_NE(outside.err.find("must lie in the glTF file's folder"), std::string::npos)
      << outside.err;

  start_master();
  start_worker();
  std::vector<std::string> args{"submit", glb.string(), "--wait", "-o",
                                (dir() / "farm.exr").string()};
  args.insert(args.end(), lit_settings.begin(), lit_settings.end());
  const RunResult r = cli(args);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(bit_identical(dir() / "farm.exr", local));
}

TEST_F(CliTest, AMitsubaSceneReadsItsRootAndParametersLocallyAndOnTheFarmAlike) {
  // A Mitsuba scene in scenes/box/ that reads its mesh from ../../common through <path>, and takes
  // its sample count and the light's colour from $name parameters.
  fs::create_directories(dir() / "mi" / "common");
  std::ofstream(dir() / "mi" / "common" / "quad.obj")
      << "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3 4\n";
  fs::create_directories(dir() / "mi" / "scenes" / "box");
  const fs::path scene = dir() / "mi" / "scenes" / "box" / "scene.xml";
  std::ofstream(scene) << R"(<scene version="3.0.0">
  <path value="../../common"/>
  <default name="spp" value="4"/>
  <default name="red" value="1"/>
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="16"/>
      <rfilter type="box"/></film>
    <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
  </sensor>
  <shape type="obj">
    <string name="filename" value="quad.obj"/>
    <emitter type="area"><rgb name="radiance" value="$red, 0.5, 0.25"/></emitter>
  </shape>
  <shape type="sphere"><point name="center" x="0" y="0" z="1"/><float name="radius" value="0.3"/></shape>
</scene>
)";
  // The root must be given: ../../common lies outside the scene's folder.
  const RunResult outside =
      cli({"render", scene.string(), "-o", (dir() / "x.exr").string()}, false);
  EXPECT_EQ(outside.code, 1);
  EXPECT_NE(outside.err.find("scene.xml:2: <path>"), std::string::npos) << outside.err;
  EXPECT_NE(outside.err.find("--scene-root"), std::string::npos) << outside.err;

  const std::vector<std::string> settings{"--scene-root", (dir() / "mi").string(), "-D", "red=2"};
  const fs::path local = local_render(scene, settings);
  EXPECT_EQ(read_exr(local).width, 24u);
  const fs::path plain = local_render(scene, {"--scene-root", (dir() / "mi").string()});
  EXPECT_FALSE(bit_identical(local, plain));  // -D red=2 changed the light

  start_master();
  start_worker();
  std::vector<std::string> args{"submit", scene.string(), "--wait", "-o",
                                (dir() / "farm.exr").string()};
  args.insert(args.end(), settings.begin(), settings.end());
  const RunResult r = cli(args);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(bit_identical(dir() / "farm.exr", local));
}

TEST_F(CliTest, ClampIsOffByDefaultRecordedWhenOnAndTheSameOnTheFarm) {
  const fs::path scene = small_scene("cornell-box", 32);
  const std::vector<std::string> plain{"--spp", "16", "--seed", "4"};
  std::vector<std::string> clamped = plain;
  clamped.insert(clamped.end(), {"--clamp", "0.5"});
  const Image unclamped_image = read_exr(local_render(scene, plain));
  const fs::path local = local_render(scene, clamped);
  const Image clamped_image = read_exr(local);
  EXPECT_EQ(unclamped_image.attributes.count("rayfarm:clamp"), 0u) << "off by default";
  ASSERT_EQ(clamped_image.attributes.count("rayfarm:clamp"), 1u);
  EXPECT_EQ(clamped_image.attributes.at("rayfarm:clamp"), "0.5");
  // The unclamped image has brighter pixels than the clamp; no mean of clamped samples can.
  EXPECT_GT(*std::max_element(unclamped_image.rgb.begin(), unclamped_image.rgb.end()), 0.5f);
  EXPECT_LE(*std::max_element(clamped_image.rgb.begin(), clamped_image.rgb.end()), 0.5f + 1e-6f);
  const RunResult negative = cli({"render", scene.string(), "-o", (dir() / "n.exr").string(),
                                  "--clamp", "-1"},
                                 false);
  EXPECT_NE(negative.code, 0);
  EXPECT_NE(negative.err.find("--clamp"), std::string::npos) << negative.err;

  start_master();
  start_worker();
  std::vector<std::string> args{"submit", scene.string(), "--wait", "-o",
                                (dir() / "farm-clamped.exr").string()};
  args.insert(args.end(), clamped.begin(), clamped.end());
  const RunResult r = cli(args);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(bit_identical(dir() / "farm-clamped.exr", local));
  EXPECT_EQ(read_exr(dir() / "farm-clamped.exr").attributes.count("rayfarm:clamp"), 1u);
}

// --- With a farm ---

TEST_F(CliTest, JsonOutputIsOneObjectPerLine) {
  start_master();
  const fs::path scene = small_scene("furnace", 16);
  const RunResult submitted = cli({"submit", scene.string(), "--spp", "8", "--json"});
  ASSERT_EQ(submitted.code, 0) << submitted.err;
  const auto lines = json_lines(submitted.out);
  ASSERT_EQ(lines.size(), 1u) << submitted.out;
  const std::string job = lines[0].at("job");
  EXPECT_EQ(lines[0].at("state"), "queued");
  EXPECT_EQ(lines[0].at("width"), 16);
  EXPECT_TRUE(lines[0].at("est_rel_mse").is_null());
  EXPECT_TRUE(lines[0].at("error").is_null());

  start_worker();
  const RunResult watched = cli({"watch", job, "--json"});
  ASSERT_EQ(watched.code, 0) << watched.err;
  const auto updates = json_lines(watched.out);
  ASSERT_FALSE(updates.empty());
  for (const json& u : updates) EXPECT_EQ(u.at("job"), job);
  EXPECT_EQ(updates.back().at("state"), "done");
  EXPECT_EQ(updates.back().at("spp_done"), 8);
  EXPECT_TRUE(updates.back().at("est_rel_mse").is_number());

  const RunResult second = cli({"submit", scene.string(), "--spp", "4"});
  ASSERT_EQ(second.code, 0);
  const RunResult list = cli({"list", "--json"});
  ASSERT_EQ(list.code, 0) << list.err;
  EXPECT_EQ(json_lines(list.out).size(), 2u) << list.out;
  const RunResult status = cli({"status", job, "--json"});
  ASSERT_EQ(status.code, 0);
  const auto one = json_lines(status.out);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].at("state"), "done");
  EXPECT_EQ(one[0].at("passes_done"), one[0].at("passes_total"));
  // Every process names its version in its first log line.
  for (const std::string& log : {master().log(), read_file(dir() / "w1.log")}) {
    EXPECT_NE(log.substr(0, log.find('\n')).find(protocol::kBuildVersion), std::string::npos)
        << log.substr(0, 300);
  }
  const RunResult workers = cli({"workers", "--json"});
  ASSERT_EQ(workers.code, 0) << workers.err;
  const auto ws = json_lines(workers.out);
  ASSERT_EQ(ws.size(), 1u) << workers.out;
  EXPECT_EQ(ws[0].at("name"), "w1");
  EXPECT_EQ(ws[0].at("key_name"), "w1");
  EXPECT_GE(ws[0].at("units_done").get<int>(), 1);
  EXPECT_GT(ws[0].at("samples_per_second").get<double>(), 0.0);
}

TEST_F(CliTest, WatchRidesOutAMasterRestart) {
  start_master();
  const fs::path scene = small_scene("cornell-box", 64);
  const std::string job = submit(scene, {"--spp", "256", "--tile", "32", "--pass-spp", "16"});
  auto watch = cli_in_background({"watch", job, "--timeout", "60"}, "watch");
  start_worker();
  wait_for_units(job, 2);
  master().signal(SIGKILL);
  ASSERT_TRUE(master().wait(milliseconds{5000}));
  std::this_thread::sleep_for(milliseconds{1500});  // long enough for a poll to go unanswered
  start_master("master-2.log");
  const RunResult r = finish(*watch, "watch", milliseconds{120000});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find(job + " done"), std::string::npos) << r.out;
  EXPECT_EQ(status(job).state(), wire::JOB_DONE);
}

/// Accepts connections on a loopback port and resets each at once: what a client meets while a
/// master behind a port proxy is not listening yet.
class HangingUpListener {
 public:
  explicit HangingUpListener(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);  // not inherited by the CLI
    const int one = 1;
    ::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    addr.sin_port = htons(static_cast<uint16_t>(port));
    ok_ = ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 && ::listen(fd_, 16) == 0;
    thread_ = std::thread([this] {
      while (!stop_) {
        timeval tv{0, 50000};
        fd_set set;
        FD_ZERO(&set);
        FD_SET(fd_, &set);
        if (::select(fd_ + 1, &set, nullptr, nullptr, &tv) <= 0) continue;
        const int c = ::accept4(fd_, nullptr, nullptr, SOCK_CLOEXEC);
        if (c < 0) continue;
        std::this_thread::sleep_for(milliseconds{20});  // the client's greeting arrives
        const linger reset{1, 0};
        ::setsockopt(c, SOL_SOCKET, SO_LINGER, &reset, sizeof reset);
        ::close(c);
        ++accepted_;
      }
    });
  }
  ~HangingUpListener() { stop(); }
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  bool ok() const { return ok_; }
  int accepted() const { return accepted_.load(); }

 private:
  int fd_ = -1;
  bool ok_ = false;
  std::atomic<bool> stop_{false};
  std::atomic<int> accepted_{0};
  std::thread thread_;
};

TEST_F(CliTest, AMasterThatHangsUpWhileStartingIsNotBlamedOnTheKey) {
  const int port = std::stoi(client_endpoint().substr(client_endpoint().rfind(':') + 1));
  {
    // Hung up on for the whole --timeout: exit 4, saying it is not just a master starting.
    HangingUpListener proxy(port);
    ASSERT_TRUE(proxy.ok());
    const RunResult r = cli({"list", "--timeout", "2"});
    EXPECT_GT(proxy.accepted(), 0);
    EXPECT_NE(r.code, 0);
    if (r.code == 4) {
      EXPECT_NE(r.err.find("not just starting"), std::string::npos) << r.err;
    } else {
      EXPECT_EQ(r.code, 3) << r.err;
      EXPECT_NE(r.err.find("starting or stopping"), std::string::npos) << r.err;
    }
  }
  // Hung up on until the master listens: the command goes through.
  HangingUpListener proxy(port);
  ASSERT_TRUE(proxy.ok());
  auto list = cli_in_background({"list", "--timeout", "60"}, "list");
  ASSERT_TRUE(wait_until([&] { return proxy.accepted() >= 2; }, milliseconds{20000}));
  proxy.stop();
  start_master();
  const RunResult r = finish(*list, "list", milliseconds{70000});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, "no jobs\n");
}

TEST_F(CliTest, CancelledJobsSayCancelledAndCanBeRetriedOrRemoved) {
  start_master();
  const fs::path scene = small_scene("furnace", 16);
  const std::vector<std::string> settings{"--spp", "8", "--seed", "5"};
  const std::string job = submit(scene, settings);
  ASSERT_EQ(cli({"cancel", job}).code, 0);
  const RunResult watched = cli({"watch", job});
  EXPECT_EQ(watched.code, 5);
  EXPECT_NE(watched.err.find("was cancelled"), std::string::npos) << watched.err;
  EXPECT_EQ(watched.err.find("failed"), std::string::npos) << watched.err;
  const RunResult shown = cli({"status", job});
  EXPECT_EQ(shown.code, 0);
  EXPECT_EQ(count_of(shown.out, "\nerror"), 0u) << shown.out;
  EXPECT_EQ(shown.out.find("failed"), std::string::npos) << shown.out;
  // Over: no estimate of when it ends, and no error figure it does not have.
  EXPECT_EQ(shown.out.find("ETA"), std::string::npos) << shown.out;
  EXPECT_EQ(shown.out.find("inf"), std::string::npos) << shown.out;

  // rm refuses a job that is not finished; retry runs a cancelled one again to the same image.
  const std::string running = submit(scene, settings);
  const RunResult busy = cli({"rm", running});
  EXPECT_EQ(busy.code, 1);
  EXPECT_NE(busy.err.find("cancel it first"), std::string::npos) << busy.err;
  const RunResult retried = cli({"retry", job});
  ASSERT_EQ(retried.code, 0) << retried.err;
  EXPECT_EQ(retried.out, "job " + job + " queued\n");
  start_worker();
  wait_for_state(job, wire::JOB_DONE);
  wait_for_state(running, wire::JOB_DONE);
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
  const RunResult again = cli({"retry", job});
  EXPECT_EQ(again.code, 1);
  EXPECT_NE(again.err.find("only a failed or cancelled job"), std::string::npos) << again.err;

  const RunResult workers = cli({"workers"});
  EXPECT_EQ(workers.code, 0);
  EXPECT_TRUE(has_line(workers.out, "w1", "idle")) << workers.out;

  ASSERT_EQ(cli({"rm", job}).code, 0);
  EXPECT_FALSE(fs::exists(job_dir(job)));
  const RunResult gone = cli({"status", job});
  EXPECT_EQ(gone.code, 1);
  EXPECT_NE(gone.err.find("unknown job '" + job + "'"), std::string::npos) << gone.err;
  EXPECT_EQ(json_lines(cli({"list", "--json"}).out).size(), 1u);
}

// A burst of changes from one key beyond its budget (20 at once, then 10 a second): the master
// refuses the excess as busy, having changed nothing, and the CLI asks again until its timeout,
// so that every command of a script that pauses, resumes or removes many jobs succeeds.
TEST_F(CliTest, ABurstOfChangesBeyondTheKeysBudgetAllSucceed) {
  start_master();
  const std::string job = submit(small_scene("furnace", 16), {"--spp", "8", "--paused"});
  constexpr int kCommands = 40;
  std::vector<std::unique_ptr<Process>> commands;
  for (int i = 0; i < kCommands; ++i) {
    commands.push_back(cli_in_background({i % 2 ? "pause" : "resume", job, "--timeout", "30"},
                                         "change-" + std::to_string(i)));
  }
  for (int i = 0; i < kCommands; ++i) {
    const RunResult r = finish(*commands[i], "change-" + std::to_string(i), milliseconds{60000});
    EXPECT_EQ(r.code, 0) << i << ": " << r.err;
    EXPECT_EQ(r.err.find("too many changes"), std::string::npos) << r.err;
  }
  EXPECT_EQ(cli({"cancel", job}).code, 0);
}

TEST_F(CliTest, AJobWhoseRecordCannotBeReadIsListedNotDropped) {
  start_master();
  const fs::path scene = small_scene("furnace", 16);
  const std::string job = submit(scene, {"--spp", "4"});
  ASSERT_EQ(cli({"cancel", job}).code, 0);
  master().signal(SIGTERM);
  ASSERT_TRUE(master().wait(milliseconds{10000}));
  std::ofstream(job_dir(job) / "job.json", std::ios::trunc) << "{\"id\": \"" << job << "\", ";
  start_master("master-2.log");
  const RunResult list = cli({"list"});
  EXPECT_EQ(list.code, 0);
  EXPECT_TRUE(has_line(list.out, job, "unknown")) << list.out;
  EXPECT_TRUE(has_line(list.out, job + ": the master cannot read", "job.json")) << list.out;
  const auto lines = json_lines(cli({"list", "--json"}).out);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].at("state"), "unknown");
  EXPECT_NE(lines[0].at("error").get<std::string>().find("job.json"), std::string::npos);
  EXPECT_EQ(cli({"watch", job}).code, 1);
  ASSERT_EQ(cli({"rm", job}).code, 0);
  EXPECT_EQ(cli({"list"}).out, "no jobs\n");
}

}  // namespace
}  // namespace rayfarm::test

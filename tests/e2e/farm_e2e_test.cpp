// The farm end to end, with real processes on loopback: a master, workers and the rayfarm CLI.
// The farm's EXR must equal `rayfarm render` of the same scene, spp and seed bit for bit, whatever
// the number of workers, a worker killed mid-job, a worker joining late or duplicate results.
// Wrong protocol versions are refused, garbage is ignored, and client errors are clear. Every
// process uses CURVE keys (made by `rayfarm keygen` and net::write_key_pair) unless a test asks
// for --insecure. Every wait is bounded; every process is killed by PID when its test ends,
// passed or failed.
#include <gtest/gtest.h>

#include <signal.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <map>
#include <memory>
#include <random>

#include <nlohmann/json.hpp>

#include "common/bundle/bundle.h"
#include "common/image/exr.h"
#include "common/net/keys.h"
#include "common/net/socket.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/scene/parser.h"
#include "tests/e2e/farm_fixture.h"
#include "renderer/renderer.h"

namespace rayfarm::test {
namespace {
class FarmTest : public FarmFixture {
 protected:
  void SetUp() override {
    FarmFixture::SetUp();
    // The master's key from the CLI, the others in-process; public keys go to the allow-lists.
    const RunResult keygen =
        cli({"keygen", "-o", keys().string(), "--name", "master"}, /*farm=*/false);
    ASSERT_EQ(keygen.code, 0) << keygen.err;
    ASSERT_NE(keygen.out.find("master.key_secret"), std::string::npos) << keygen.out;
    master_keys_ = net::read_key_pair(keys() / "master.key_secret");
    client_keys_ = peer_key("cli", "clients");
  }

  /// A key pair named `name`, its secret file in keys/own/, its public one in keys/`list`/ (the
  /// master's allow-list "workers" or "clients") unless `list` is empty.
  net::KeyPair peer_key(const std::string& name, const std::string& list) {
    const fs::path secret = keys() / "own" / (name + ".key_secret");
    if (!fs::exists(secret)) {
      net::write_key_pair(keys() / "own", name, net::generate_key_pair());
      if (!list.empty()) {
        fs::create_directories(keys() / list);
        fs::copy_file(keys() / "own" / (name + ".key"), keys() / list / (name + ".key"));
      }
    }
    return net::read_key_pair(secret);
  }
  fs::path keys() const { return dir() / "keys"; }
  fs::path secret_file(const std::string& name) const {
    return keys() / "own" / (name + ".key_secret");
  }
  fs::path master_public_file() const { return keys() / "master.key"; }
  /// A raw peer's CURVE settings with `keys`.
  net::Curve curve(const net::KeyPair& keys) const {
    return {keys.public_key, keys.secret_key, master_keys_.public_key, ""};
  }
  /// The CLI and raw clients use the test's client key.
  std::vector<std::string> client_auth() const override {
    return {"--key", secret_file("cli").string(), "--master-key", master_public_file().string()};
  }
  net::Curve client_curve() const override { return curve(client_keys_); }
  /// A raw client with the test's client key, and a raw worker with its own listed key.
  RawPeer client_peer() { return RawPeer(client_endpoint(), client_curve()); }
  RawPeer worker_peer(const std::string& name) {
    return RawPeer(worker_endpoint(), curve(peer_key(name, "workers")));
  }

  /// Starts the master (again, after a crash, with `log` another file: the log is appended to),
  /// with its key and allow-lists, and `extra` options.
  /// `liveness` counts heartbeats of 200 ms: 3 lets tests about lost workers run quickly.
  void start_master(const std::string& log = "master.log",
                    const std::vector<std::string>& extra = {}, int liveness = 3) {
    fs::create_directories(keys() / "workers");
    std::vector<std::string> options{"--heartbeat-ms",
                                     "200",
                                     "--liveness",
                                     std::to_string(liveness),
                                     "--image-interval-ms",
                                     "500",
                                     "--key",
                                     (keys() / "master.key_secret").string(),
                                     "--worker-keys",
                                     (keys() / "workers").string(),
                                     "--client-keys",
                                     (keys() / "clients").string()};
    options.insert(options.end(), extra.begin(), extra.end());
    run_master(log, options);
  }

  /// Starts a worker with its own key, on the master's allow-list; `auth` replaces the key
  /// options (e.g. another key, or --insecure).
  Process& start_worker(const std::string& name, int threads = 1,
                        std::optional<std::vector<std::string>> auth = std::nullopt) {
    if (!auth) {
      peer_key(name, "workers");
      auth = std::vector<std::string>{"--key", secret_file(name).string(), "--master-key",
                                      master_public_file().string()};
    }
    std::vector<std::string> options{"--threads",    std::to_string(threads), "--heartbeat-ms",
                                     "200",          "--liveness",            "3",
                                     "--reconnect-max-ms", "1000"};
    options.insert(options.end(), auth->begin(), auth->end());
    return run_worker(name, options);
  }

 private:
  net::KeyPair master_keys_, client_keys_;
};

TEST_F(FarmTest, TwoWorkersRenderTheCornellBoxBitIdenticalToALocalRender) {
  start_master();
  Process& a = start_worker("wa", 2);  // two threads: two units at once
  Process& b = start_worker("wb");
  // Both workers are in before the job: otherwise one may render all of it alone.
  ASSERT_TRUE(wait_until(
      [&] {
        const std::string log = master().log();
        return has_line(log, "worker wa (", ") joined") && has_line(log, "worker wb (", ") joined");
      },
      milliseconds{30000}))
      << master().log();
  const fs::path scene = small_scene("cornell-box", 64);
  const std::vector<std::string> settings{"--spp",       "32", "--seed",       "7",
                                          "--max-depth", "6",  "--integrator", "mis"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "16", "--pass-spp", "8"});
  const std::string job = submit(scene, job_settings, /*wait=*/true);
  ASSERT_EQ(job, "j0001");

  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
  const std::string log = master().log();
  EXPECT_NE(log.find("job j0001 pass 4/4 done"), std::string::npos);
  EXPECT_NE(log.find("job j0001 done"), std::string::npos);

  const RunResult st = cli({"status", job});
  EXPECT_EQ(st.code, 0);
  EXPECT_NE(st.out.find("done"), std::string::npos) << st.out;
  const RunResult list = cli({"list"});
  EXPECT_NE(list.out.find("j0001"), std::string::npos) << list.out;

  // Both workers took part, and all three processes stop cleanly on SIGTERM.
  a.signal(SIGTERM);
  b.signal(SIGTERM);
  EXPECT_EQ(a.wait(milliseconds{10000}), std::optional<int>(0));
  EXPECT_EQ(b.wait(milliseconds{10000}), std::optional<int>(0));
  EXPECT_NE(a.log().find("job j0001: rendered"), std::string::npos) << a.log();
  EXPECT_NE(b.log().find("job j0001: rendered"), std::string::npos) << b.log();
  EXPECT_TRUE(wait_until(
      [&] { return master().log().find("left (stopped)") != std::string::npos; },
      milliseconds{10000}))
      << master().log();
  master().signal(SIGTERM);
  EXPECT_EQ(master().wait(milliseconds{10000}), std::optional<int>(0));
}

TEST_F(FarmTest, AnAdaptiveJobStopsTileByTileAndEqualsTheLocalRender) {
  // Under a target error, which units a job merges depends only on the scene and the settings,
  // never on which worker returned what when: the farm's image is still the local one, bit for
  // bit, and the tiles that converged got fewer samples than the noisy ones.
  start_master();
  start_worker("wa", 2);
  start_worker("wb");
  const fs::path scene = small_scene("cornell-box", 32);
  const std::vector<std::string> settings{"--spp",      "1024", "--seed",         "3",
                                          "--max-depth", "6",   "--target-error", "2e-2",
                                          "--tile",      "16",  "--pass-spp",     "16"};
  const fs::path local = local_render(scene, settings);
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--reference", local.string()});
  const std::string job = submit(scene, job_settings, /*wait=*/true);
  EXPECT_TRUE(bit_identical(fetch(job), local));

  const wire::JobStatus st = status(job);
  EXPECT_EQ(st.state(), wire::JOB_DONE);
  EXPECT_GT(st.tiles_converged(), 0u);
  EXPECT_LT(st.units_done(), st.units_total()) << "no tile stopped early";
  EXPECT_LT(st.spp_done(), 1024u);
  EXPECT_TRUE(st.stop_reason() == "target error" || st.stop_reason() == "spp") << st.stop_reason();
  EXPECT_GT(st.est_rel_mse(), 0.0);
  EXPECT_EQ(st.ref_rel_mse(), 0.0) << "measured against the identical local image";

  // The error record: every pass logged with its estimate, and `rayfarm report` draws the plot.
  EXPECT_NE(master().log().find("estimated relMSE"), std::string::npos);
  const RunResult report = cli({"report", job, "-o", (fs::path(local).parent_path() / "plot.png").string()});
  EXPECT_EQ(report.code, 0) << report.err;
  EXPECT_NE(report.out.find("stop"), std::string::npos) << report.out;
  EXPECT_TRUE(fs::exists(fs::path(local).parent_path() / "plot.png"));
}

TEST_F(FarmTest, LeasesSizedByTimeCoverRunsOfPassesAndChangeNoBit) {
  // Units of a few milliseconds and a target of 30 s a lease: once a worker's time per unit is
  // measured, each lease covers as many of a tile's passes as allowed, and one result returns
  // their sums. The image is the local one, bit for bit, with a pixel filter whose samples land
  // in the neighbouring tiles' pixels too (a Gaussian of radius 2).
  start_master("master.log",
               {"--log-level", "debug", "--unit-seconds", "30", "--max-run-units", "8"});
  start_worker("wa", 2);
  start_worker("wb");
  const fs::path scene = small_scene("cornell-box", 32, "gaussian");
  const std::vector<std::string> settings{"--spp", "64", "--seed", "11", "--max-depth", "6"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "16", "--pass-spp", "2"});  // 4 x 32 units
  const std::string job = submit(scene, job_settings, /*wait=*/true);
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
  EXPECT_EQ(status(job).units_done(), 128u);
  const std::string log = master().log();
  EXPECT_TRUE(has_line(log, "j0001 unit ", "(passes ")) << "no lease covered a run";
  EXPECT_TRUE(has_line(log, "and the next 7 of its tile merged from", "")) << "no run of 8";
  EXPECT_LT(count_of(log, "merged from"), 64u) << "results: one per run, not one per unit";
}

TEST_F(FarmTest, AWorkerKilledMidJobLosesNothing) {
  start_master();
  Process& victim = start_worker("victim");
  start_worker("survivor");
  // An OBJ and an MTL travel in the bundle; the Mitchell filter's negative lobes make samples of
  // either sign.
  const fs::path scene = small_scene("embree-cornell", 64, "mitchell");
  const std::vector<std::string> settings{"--spp", "1024", "--seed", "3"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "32", "--pass-spp", "128"});  // 32 units
  const std::string job = submit(scene, job_settings);
  wait_for_units(job, 4);

  // Kill the victim while it holds a lease (one unit, or a run of its tile's passes): stopped,
  // both workers hold leases.
  bool killed = false;
  for (int attempt = 0; attempt < 50 && !killed; ++attempt) {
    victim.signal(SIGSTOP);
    std::this_thread::sleep_for(milliseconds{30});
    if (status(job).workers_busy() == 2) {
      victim.signal(SIGKILL);
      killed = true;
    } else {
      victim.signal(SIGCONT);
      std::this_thread::sleep_for(milliseconds{30});
    }
  }
  ASSERT_TRUE(killed) << "the victim never held a lease";
  EXPECT_EQ(victim.wait(milliseconds{5000}), std::optional<int>(128 + SIGKILL));
  wait_for_state(job, wire::JOB_DONE);

  const std::string log = master().log();
  EXPECT_NE(log.find("worker victim"), std::string::npos);
  EXPECT_TRUE(has_line(log, "worker victim (", ") lost: silent for"))
      << "no loss in the master log";
  EXPECT_TRUE(has_line(log, "requeued ", " of worker victim ("))
      << "no requeue in the master log";
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
}

TEST_F(FarmTest, AWorkerThatJoinsLateTakesWork) {
  start_master("master.log", {}, /*liveness=*/100);  // 20 s: the early worker is stopped a while
  Process& early = start_worker("early");
  const fs::path scene = small_scene("cornell-box", 64);
  const std::vector<std::string> settings{"--spp", "512", "--seed", "11"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "32", "--pass-spp", "32"});  // 64 units
  const std::string job = submit(scene, job_settings);
  wait_for_units(job, 4);
  // The early worker waits (frozen, its lease safe within the 20 s liveness window) until
  // the late one has asked for work: otherwise it may finish the job before the late one is in.
  early.signal(SIGSTOP);
  Process& late = start_worker("late");
  const bool asked = wait_until(
      [&] { return late.log().find("fetching bundle") != std::string::npos; }, milliseconds{30000});
  early.signal(SIGCONT);
  ASSERT_TRUE(asked) << late.log();
  wait_for_state(job, wire::JOB_DONE);
  late.signal(SIGTERM);
  ASSERT_EQ(late.wait(milliseconds{10000}), std::optional<int>(0));
  const std::string late_log = late.log();
  const std::string marker = "job j0001: rendered ";
  const size_t at = late_log.find(marker);
  ASSERT_NE(at, std::string::npos) << late_log;
  EXPECT_GT(std::stoi(late_log.substr(at + marker.size())), 0) << late_log;
  EXPECT_TRUE(has_line(master().log(), "worker late (", ") joined"));
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
}

TEST_F(FarmTest, WorkersReconnectWhenTheMasterRestarts) {
  start_master();
  Process& worker = start_worker("steady");
  const fs::path scene = small_scene("cornell-box", 64);
  const std::vector<std::string> settings{"--spp", "512", "--seed", "2"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "32", "--pass-spp", "32"});  // 64 units
  const std::string job = submit(scene, job_settings);
  wait_for_units(job, 4);

  // A master that comes back at once: the connection heals by itself, the worker says hello again.
  master().signal(SIGKILL);
  ASSERT_TRUE(master().wait(milliseconds{5000}));
  start_master("master-2.log");  // same ports, same data dir: the job resumes (checkpoint.h)
  EXPECT_TRUE(master().log().find("job j0001 resumed from checkpoint at ") != std::string::npos ||
              master().log().find("job j0001 restarted from the beginning") != std::string::npos)
      << master().log();
  // The resumed job may already count the units we waited for: wait for the worker's second hello
  // and for new units merged by this master.
  ASSERT_TRUE(wait_until([&] { return count_of(worker.log(), "connected to the master") >= 2; },
                         milliseconds{10000}))
      << worker.log();
  const uint64_t resumed = status(job).units_done();
  wait_for_units(job, std::min<uint64_t>(resumed + 2, 64));

  // A master away for longer than the liveness window: the worker reconnects with back-off.
  const size_t silences = count_of(worker.log(), "is silent for");
  master().signal(SIGKILL);
  ASSERT_TRUE(master().wait(milliseconds{5000}));
  ASSERT_TRUE(wait_until([&] { return count_of(worker.log(), "is silent for") > silences; },
                         milliseconds{10000}));
  std::this_thread::sleep_for(milliseconds{1500});
  start_master("master-3.log");
  wait_for_state(job, wire::JOB_DONE);
  EXPECT_TRUE(has_line(master().log(), "worker steady (", ") joined"));
  // Three hellos at least: on a loaded machine a missed heartbeat may add one more.
  EXPECT_GE(count_of(worker.log(), "connected to the master"), 3u) << worker.log();
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
}

TEST_F(FarmTest, ADuplicateResultIsDroppedAndChangesNothing) {
  peer_key("twice", "workers");
  // One unit per lease (--unit-seconds 0): the fake asks for each of the 8 units.
  start_master("master.log", {"--unit-seconds", "0"}, /*liveness=*/100);  // 20 s: no heartbeats
  const fs::path scene = small_scene("cornell-box", 32);
  const std::vector<std::string> settings{"--spp", "16", "--seed", "5"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "16", "--pass-spp", "8"});  // 8 units
  const std::string job = submit(scene, job_settings);

  // A worker of our own that sends every result twice.
  RawPeer fake = worker_peer("twice");
  wire::Hello hello;
  hello.set_role(wire::ROLE_WORKER);
  hello.set_name("twice");
  fake.send(protocol::encode(hello));
  fake.expect<wire::Welcome>();
  std::unique_ptr<Scene> loaded;
  std::unique_ptr<Renderer> renderer;
  for (int i = 0; i < 8; ++i) {
    fake.send(protocol::encode(wire::WorkRequest{}));
    const auto unit = fake.expect<wire::WorkUnit>();
    if (!renderer) {
      wire::BundleRequest request;
      request.set_hash(unit.bundle_hash());
      fake.send(protocol::encode(request));
      const auto reply = fake.expect<wire::BundleReply>();
      ASSERT_TRUE(reply.error().empty()) << reply.error();
      const fs::path unpacked = unpack_bundle(protocol::bundle_from_wire(reply.bundle()),
                                              dir() / "fake-cache", unit.bundle_hash());
      loaded = std::make_unique<Scene>(load_scene(unpacked / unit.scene_path()));
      renderer = std::make_unique<Renderer>(*loaded, protocol::settings_from_wire(unit.settings()));
    }
    const TileResult result = renderer->render(protocol::rect_from_wire(unit.tile()),
                                               {unit.sample_begin(), unit.sample_end()});
    const net::Frames frames =
        protocol::encode(protocol::result_to_wire(unit.job_id(), unit.unit_id(), result, 0.0));
    fake.send(frames);
    fake.send(frames);
  }
  wait_for_state(job, wire::JOB_DONE);
  ASSERT_TRUE(wait_until(
      [&] { return count_of(master().log(), "duplicate result from worker twice") == 8; },
      milliseconds{5000}))
      << master().log();
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
}

TEST_F(FarmTest, APeerWithAnotherProtocolVersionIsRefused) {
  peer_key("future", "workers");
  start_master();
  for (const auto& [endpoint, role] : {std::pair{client_endpoint(), wire::ROLE_CLIENT},
                                       std::pair{worker_endpoint(), wire::ROLE_WORKER}}) {
    RawPeer peer = role == wire::ROLE_CLIENT ? client_peer() : worker_peer("future");
    wire::Hello hello;
    hello.set_role(role);
    hello.set_name("from-the-future");
    peer.send(protocol::encode(hello, protocol::kProtocolVersion + 1));
    const auto refusal = peer.expect<wire::Refusal>();
    EXPECT_EQ(refusal.master_version(), protocol::kProtocolVersion);
    EXPECT_EQ(refusal.peer_version(), protocol::kProtocolVersion + 1);
    const std::string ours = std::to_string(protocol::kProtocolVersion);
    const std::string theirs = std::to_string(protocol::kProtocolVersion + 1);
    EXPECT_NE(refusal.reason().find("version " + ours), std::string::npos) << refusal.reason();
    EXPECT_NE(refusal.reason().find("version " + theirs), std::string::npos) << refusal.reason();
  }
  EXPECT_EQ(count_of(master().log(),
                     "it speaks protocol version " +
                         std::to_string(protocol::kProtocolVersion + 1) + ", this master " +
                         std::to_string(protocol::kProtocolVersion)),
            2u)
      << master().log();
  EXPECT_EQ(cli({"list"}).code, 0);
}

TEST_F(FarmTest, GarbageOnEitherSocketIsLoggedAndIgnored) {
  peer_key("garbage", "workers");
  peer_key("w", "workers");
  start_master();
  std::mt19937 rng(9);
  std::string noise(300, '\0');
  for (char& c : noise) c = static_cast<char>(rng());
  const std::vector<net::Frames> garbage{
      {"just one frame"},
      {"a", "b", "c"},
      {"rayfarm.wire.NoSuchMessage", "x"},
      {"rayfarm.wire.SubmitJob", "\xff\xff\xff\xff"},
      {std::string(1000, 't'), ""},
      {noise, noise},
      {"", ""},
  };
  RawPeer client = client_peer();
  RawPeer worker = worker_peer("garbage");
  for (const auto& frames : garbage) {
    client.send(frames);
    worker.send(frames);
  }
  // The client socket answers each bad request with an error; the worker socket stays silent.
  for (size_t i = 0; i < garbage.size(); ++i) {
    const auto error = client.expect<wire::Error>();
    EXPECT_NE(error.message().find("cannot decode"), std::string::npos) << error.message();
    EXPECT_EQ(error.code(), wire::Error::BAD_REQUEST) << error.message();
  }
  // Logged once per socket and key, not once per message (a peer cannot flood the log).
  EXPECT_TRUE(wait_until(
      [&] { return count_of(master().log(), "ignored a bad message") == 2; }, milliseconds{5000}))
      << master().log();
  // A valid message on the wrong socket is refused by name.
  worker.send(protocol::encode(wire::ListJobs{}));
  const auto unknown = worker.expect<wire::Error>();
  EXPECT_NE(unknown.message().find("unknown worker"), std::string::npos);
  EXPECT_EQ(unknown.code(), wire::Error::UNKNOWN_WORKER);

  // The master still serves: a job renders and matches.
  ASSERT_TRUE(master().running());
  start_worker("w");
  const fs::path scene = small_scene("cornell-box", 32);
  const std::vector<std::string> settings{"--spp", "8"};
  const std::string job = submit(scene, settings, /*wait=*/true);
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
}

TEST_F(FarmTest, ClientErrorsAreClear) {
  // No master: a clear error and exit code 3 within the timeout, never a hang.
  {
    const auto start = Clock::now();
    const RunResult r = cli({"list", "--timeout", "1"});
    EXPECT_EQ(r.code, 3);
    EXPECT_NE(r.err.find("cannot reach master at " + client_endpoint() + " within 1 s"),
              std::string::npos)
        << r.err;
    EXPECT_LT(Clock::now() - start, seconds{8});
  }
  start_master();
  for (const auto& command : {std::vector<std::string>{"status", "j9999"},
                              {"cancel", "j9999"},
                              {"watch", "j9999"},
                              {"fetch", "j9999", "-o", (dir() / "x.exr").string()}}) {
    const RunResult r = cli(command);
    EXPECT_EQ(r.code, 1) << command[0];
    EXPECT_NE(r.err.find("unknown job 'j9999'"), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(dir() / "x.exr"));

  // A bad scene is caught by the CLI before sending, naming the file...
  const fs::path bad = dir() / "bad" / "scene.json";
  fs::create_directories(bad.parent_path());
  std::ofstream(bad) << "{\"film\": {\"width\": -3}}";
  const RunResult r = cli({"submit", bad.string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("scene.json"), std::string::npos) << r.err;
  // ...and by the master, which returns the parser's message.
  RawPeer client = client_peer();
  wire::SubmitJob request;
  protocol::bundle_to_wire(make_bundle({{"scene.json", "{\"film\": {\"width\": -3}}"}}),
                           request.mutable_bundle());
  request.set_scene_path("scene.json");
  client.send(protocol::encode(request));
  const auto reply = client.expect<wire::SubmitReply>();
  EXPECT_TRUE(reply.job_id().empty());
  EXPECT_EQ(reply.code(), wire::Error::REFUSED);
  EXPECT_NE(reply.error().find("scene.json"), std::string::npos) << reply.error();
  EXPECT_EQ(reply.error().find(dir().string()), std::string::npos) << reply.error();

  // Cancelling a queued job (no workers) ends it, and submit --wait reports it.
  const fs::path scene = small_scene("furnace", 16);
  const std::string job = submit(scene, {"--spp", "4"});
  const RunResult cancelled = cli({"cancel", job});
  EXPECT_EQ(cancelled.code, 0);
  EXPECT_NE(cancelled.out.find("cancelled"), std::string::npos);
  EXPECT_EQ(cli({"watch", job}).code, 5);
}

// --- Keys and limits ---

TEST_F(FarmTest, AClientWithAWrongKeyIsRefusedClearlyAndTheMasterLogsItsAddress) {
  const net::KeyPair mallory = peer_key("mallory", "");  // on no allow-list
  peer_key("w1", "workers");
  start_master();
  {
    const auto start = Clock::now();
    const RunResult r =
        cli({"list", "--timeout", "30"}, true, milliseconds{60000},
            std::vector<std::string>{"--key", secret_file("mallory").string(), "--master-key",
                                     master_public_file().string()});
    EXPECT_EQ(r.code, 4) << r.err;
    EXPECT_NE(r.err.find("the master at " + client_endpoint() +
                         " did not let this client in: authentication refused"),
              std::string::npos)
        << r.err;
    EXPECT_LT(Clock::now() - start, seconds{15}) << "the refusal should not wait for --timeout";
  }
  // A worker's key cannot be used to submit either.
  {
    const RunResult r =
        cli({"list", "--timeout", "5"}, true, milliseconds{20000},
            std::vector<std::string>{"--key", secret_file("w1").string(), "--master-key",
                                     master_public_file().string()});
    EXPECT_EQ(r.code, 4) << r.err;
    EXPECT_NE(r.err.find("authentication refused"), std::string::npos) << r.err;
  }
  // The right client key with a wrong master key: the master hangs up, and the message says why.
  {
    const RunResult r =
        cli({"list", "--timeout", "5"}, true, milliseconds{20000},
            std::vector<std::string>{"--key", secret_file("cli").string(), "--master-key",
                                     net::generate_key_pair().public_key});
    EXPECT_EQ(r.code, 4) << r.err;
    EXPECT_NE(r.err.find("closed the connection during the CURVE handshake"), std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("(--master-key) is probably wrong"), std::string::npos) << r.err;
  }
  // A plain (--insecure) client has no key that could be wrong: however the master hangs up on
  // it, it is told that the master uses CURVE, every time.
  for (int run = 0; run < 5; ++run) {
    const RunResult r = cli({"list", "--timeout", "5"}, true, milliseconds{20000},
                            std::vector<std::string>{"--insecure"});
    EXPECT_EQ(r.code, 4) << r.err;
    EXPECT_NE(r.err.find("the peer uses another security mechanism: it has CURVE keys and this "
                         "side runs --insecure"),
              std::string::npos)
        << "run " << run << ": " << r.err;
    EXPECT_EQ(r.err.find("--master-key) is probably wrong"), std::string::npos) << r.err;
  }
  ASSERT_TRUE(wait_until(
      [&] {
        return has_line(
            master().log(),
            "refused a client connection from 127.0.0.1: key " + net::key_label(mallory.public_key),
            "is not on the clients allow-list");
      },
      milliseconds{5000}))
      << master().log();
  EXPECT_TRUE(has_line(master().log(), "refused a client connection from 127.0.0.1",
                       "(it is workers key 'w1')"))
      << master().log();
  // No key at all: the CLI says what to give before it tries.
  const RunResult none = cli({"list"}, true, milliseconds{20000}, std::vector<std::string>{});
  EXPECT_EQ(none.code, 1);
  EXPECT_NE(none.err.find("--key FILE"), std::string::npos) << none.err;
  // The master serves its own clients all along.
  EXPECT_EQ(cli({"list"}).code, 0);
}

TEST_F(FarmTest, AnUnknownKeyPosingAsAWorkerGetsNoWork) {
  peer_key("impostor", "");  // not on the workers' list
  start_master();
  const fs::path scene = small_scene("furnace", 16);
  const std::string job = submit(scene, {"--spp", "8", "--tile", "8"});
  Process& impostor =
      start_worker("impostor", 1,
                   std::vector<std::string>{"--key", secret_file("impostor").string(),
                                            "--master-key", master_public_file().string()});
  // The client's own key posing as a worker: refused too.
  Process& client_as_worker =
      start_worker("client-key", 1,
                   std::vector<std::string>{"--key", secret_file("cli").string(), "--master-key",
                                            master_public_file().string()});
  ASSERT_TRUE(wait_until(
      [&] {
        return impostor.log().find("did not let this worker in: authentication refused") !=
                   std::string::npos &&
               client_as_worker.log().find("authentication refused") != std::string::npos;
      },
      milliseconds{10000}))
      << impostor.log() << client_as_worker.log();
  EXPECT_NE(impostor.log().find("add this worker's public key to the master's --worker-keys"),
            std::string::npos)
      << impostor.log();
  std::this_thread::sleep_for(milliseconds{500});
  const wire::JobStatus st = status(job);
  EXPECT_EQ(st.units_done(), 0u);
  EXPECT_EQ(st.units_leased(), 0u);
  EXPECT_EQ(st.workers_total(), 0u);
  const std::string log = master().log();
  EXPECT_TRUE(has_line(log, "refused a worker connection from 127.0.0.1: key ",
                       "is not on the workers allow-list"))
      << log;
  EXPECT_TRUE(has_line(log, "refused a worker connection from 127.0.0.1", "(it is clients key"))
      << log;
  EXPECT_EQ(log.find("joined"), std::string::npos) << log;
  EXPECT_TRUE(impostor.running());  // it keeps knocking, in case its key is added

  // A listed worker does the job.
  start_worker("honest");
  wait_for_state(job, wire::JOB_DONE);
  EXPECT_TRUE(has_line(master().log(), "worker honest (", "joined with key 'honest'"))
      << master().log();
}

TEST_F(FarmTest, SubmissionsOverALimitAreRefusedByNameWhileOthersComplete) {
  start_master("master.log", {"--max-queued-jobs", "2", "--max-spp", "64", "--max-image-pixels",
                              "1024", "--max-bundle-mb", "1", "--max-message-mb", "3"});
  const fs::path small = small_scene("furnace", 16);
  const std::string a = submit(small, {"--spp", "16", "--tile", "8"});
  {
    const RunResult r = cli({"submit", small_scene("cornell-box", 48).string()});
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("the master rejected the job: the image is 48x48 = 2304 pixels, over "
                         "the master's limit of 1024 pixels (--max-image-pixels)"),
              std::string::npos)
        << r.err;
  }
  {
    const RunResult r = cli({"submit", small.string(), "--spp", "1000"});
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("1000 samples per pixel is over the master's limit of 64 spp (--max-spp)"),
              std::string::npos)
        << r.err;
  }
  // A bundle over --max-bundle-mb gets a refusal; a message over --max-message-mb is cut off by
  // ZeroMQ, and the master goes on serving.
  const std::string scene_text = "{\"film\": {\"width\": 8, \"height\": 8}}";
  for (const size_t extra : {size_t{2} << 20, size_t{4} << 20}) {
    RawPeer client = client_peer();
    wire::SubmitJob request;
    protocol::bundle_to_wire(
        make_bundle({{"scene.json", scene_text}, {"padding.bin", std::string(extra, 'x')}}),
        request.mutable_bundle());
    request.set_scene_path("scene.json");
    client.send(protocol::encode(request));
    auto reply = client.receive(milliseconds{extra > (size_t{3} << 20) ? 1000 : 10000});
    if (extra < (size_t{3} << 20)) {
      ASSERT_TRUE(reply && reply->as<wire::SubmitReply>());
      EXPECT_NE(reply->as<wire::SubmitReply>()->error().find(
                    "over the master's limit of 1.0 MiB (--max-bundle-mb)"),
                std::string::npos)
          << reply->as<wire::SubmitReply>()->error();
    } else {
      EXPECT_FALSE(reply) << "a message over --max-message-mb was answered";
    }
  }
  const std::string b = submit(small, {"--spp", "8", "--tile", "8"});
  {
    const RunResult r = cli({"submit", small.string()});
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("the master's queue is full: 2 jobs are queued or running, the limit is 2 "
                         "(--max-queued-jobs)"),
              std::string::npos)
        << r.err;
  }
  EXPECT_GE(count_of(master().log(), "job refused"), 4u) << master().log();
  start_worker("w");
  wait_for_state(a, wire::JOB_DONE);
  wait_for_state(b, wire::JOB_DONE);
  EXPECT_EQ(cli({"list"}).code, 0);
}

TEST_F(FarmTest, InsecureWorksOnLoopbackOnlyAndSaysSoLoudly) {
  // A master with plain sockets on a public endpoint refuses to start, and so does one without
  // keys that did not ask for --insecure.
  const std::vector<std::string> base{bin("master/rayfarm-master"), "--client-endpoint",
                                      client_endpoint(), "--data-dir", (dir() / "data").string()};
  {
    std::vector<std::string> argv = base;
    argv.insert(argv.end(), {"--insecure", "--worker-endpoint",
                             "tcp://0.0.0.0:" + std::to_string(free_port())});
    Process p(argv, dir() / "public.log");
    EXPECT_EQ(p.wait(milliseconds{10000}), std::optional<int>(1));
    EXPECT_NE(p.log().find("--insecure is allowed only on loopback endpoints"), std::string::npos)
        << p.log();
  }
  {
    std::vector<std::string> argv = base;
    argv.insert(argv.end(), {"--worker-endpoint", worker_endpoint()});
    Process p(argv, dir() / "keyless.log");
    EXPECT_EQ(p.wait(milliseconds{10000}), std::optional<int>(1));
    EXPECT_NE(p.log().find("the master needs its key"), std::string::npos) << p.log();
  }
  // Workers and clients refuse --insecure towards a master that is not on loopback.
  {
    Process w({bin("worker/rayfarm-worker"), "--insecure", "--master", "tcp://192.0.2.1:5555",
               "--cache-dir", (dir() / "c").string()},
              dir() / "public-worker.log");
    EXPECT_EQ(w.wait(milliseconds{10000}), std::optional<int>(1));
    EXPECT_NE(w.log().find("--insecure is allowed only with a master on loopback"),
              std::string::npos)
        << w.log();
    const RunResult r = cli({"list", "--insecure", "--master", "tcp://192.0.2.1:5556"}, false);
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("--insecure is allowed only with a master on loopback"), std::string::npos)
        << r.err;
  }
  // On loopback it works, with a warning in every log.
  {
    std::vector<std::string> argv = base;
    argv.insert(argv.end(), {"--insecure", "--worker-endpoint", worker_endpoint(),
                             "--heartbeat-ms", "200", "--liveness", "3"});
    Process m(argv, dir() / "insecure-master.log");
    ASSERT_TRUE(wait_until([&] { return m.log().find("master listening") != std::string::npos; },
                           milliseconds{10000}))
        << m.log();
    EXPECT_NE(m.log().find("INSECURE: no authentication and no encryption"), std::string::npos);
    Process& w = start_worker("plain", 1, std::vector<std::string>{"--insecure"});
    const std::vector<std::string> plain{"--insecure"};
    const RunResult r = cli({"submit", small_scene("furnace", 16).string(), "--spp", "4", "--wait"},
                            true, milliseconds{60000}, plain);
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.err.find("INSECURE"), std::string::npos) << r.err;
    EXPECT_NE(w.log().find("INSECURE"), std::string::npos) << w.log();
    // A client with keys cannot talk to a plain master: it is told the mechanisms differ.
    const RunResult keyed = cli({"list", "--timeout", "5"});
    EXPECT_EQ(keyed.code, 4) << keyed.err;
    EXPECT_NE(keyed.err.find("--insecure"), std::string::npos) << keyed.err;
  }
}

}  // namespace
}  // namespace rayfarm::test

// The farm end to end, with real processes on loopback: a master, workers and the rayfarm CLI.
// The farm's EXR must equal `rayfarm render` of the same scene, spp and seed bit for bit, whatever
// the number of workers, a worker killed mid-job, a worker joining late or duplicate results.
// Wrong protocol versions are refused, garbage is ignored, and client errors are clear. Every wait
// is bounded; every process is killed by PID when its test ends, passed or failed.
#include <gtest/gtest.h>

#include <signal.h>

#include <atomic>
#include <cstring>
#include <map>
#include <memory>
#include <random>

#include <nlohmann/json.hpp>

#include "common/bundle/bundle.h"
#include "common/image/exr.h"
#include "common/net/socket.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "common/scene/parser.h"
#include "tests/e2e/process.h"
#include "worker/renderer.h"

namespace rayfarm::test {
namespace {
namespace fs = std::filesystem;
namespace protocol = rayfarm::protocol;
namespace wire = rayfarm::wire;
using std::chrono::seconds;

std::string bin(const std::string& relative) {
  return (fs::path(RAYFARM_BINARY_DIR) / relative).string();
}

std::string read_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// True when some line of `text` holds `first` and, after it, `then`.
bool has_line(const std::string& text, const std::string& first, const std::string& then) {
  for (size_t start = 0; start < text.size();) {
    const size_t end = std::min(text.find('\n', start), text.size());
    const std::string line = text.substr(start, end - start);
    const size_t a = line.find(first);
    if (a != std::string::npos && line.find(then, a + first.size()) != std::string::npos)
      return true;
    start = end + 1;
  }
  return false;
}

struct RunResult {
  int code = -1;
  std::string out, err;
};

/// Two images hold the same float bits in the same layout.
::testing::AssertionResult bit_identical(const fs::path& a, const fs::path& b) {
  const Image x = read_exr(a), y = read_exr(b);
  if (x.width != y.width || x.height != y.height) {
    return ::testing::AssertionFailure() << "sizes differ: " << x.width << "x" << x.height << " vs "
                                         << y.width << "x" << y.height;
  }
  if (x.rgb.size() != y.rgb.size() ||
      std::memcmp(x.rgb.data(), y.rgb.data(), x.rgb.size() * sizeof(float)) != 0) {
    size_t differing = 0;
    for (size_t i = 0; i < std::min(x.rgb.size(), y.rgb.size()); ++i)
      differing += x.rgb[i] != y.rgb[i];
    return ::testing::AssertionFailure() << differing << " of " << x.rgb.size() << " values differ";
  }
  bool any_light = false;
  for (float v : x.rgb) any_light |= v > 0.f;
  if (!any_light) return ::testing::AssertionFailure() << "the image is black";
  return ::testing::AssertionSuccess();
}

/// A raw DEALER peer speaking the codec, for what the CLI and the worker never send.
class RawPeer {
 public:
  explicit RawPeer(const std::string& endpoint) : socket_(endpoint) {}
  void send(const net::Frames& frames) { ASSERT_TRUE(socket_.send(frames)); }
  /// The next message that is not a heartbeat, within `timeout`.
  std::optional<protocol::Decoded> receive(milliseconds timeout = milliseconds{10000}) {
    const auto deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      auto frames = socket_.receive(milliseconds{50});
      if (!frames) continue;
      protocol::Decoded d = protocol::decode(*frames);
      if (d.as<wire::Heartbeat>()) continue;
      return d;
    }
    return std::nullopt;
  }
  template <class T>
  T expect(milliseconds timeout = milliseconds{10000}) {
    auto d = receive(timeout);
    if (!d)
      throw std::runtime_error(std::string("no reply, expected ") + T::descriptor()->full_name());
    if (const T* m = d->as<T>()) return *m;
    throw std::runtime_error("got " + d->type + ", expected " + T::descriptor()->full_name());
  }

 private:
  net::Dealer socket_;
};

class FarmTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    dir_ = fs::temp_directory_path() /
           ("rayfarm-e2e-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    fs::create_directories(dir_);
    worker_port_ = free_port();
    client_port_ = free_port();
  }

  void TearDown() override {
    if (HasFailure()) {
      if (master_) std::cerr << "---- master log ----\n" << master_->log() << "\n";
      for (const auto& [name, w] : workers_)
        std::cerr << "---- " << name << " log ----\n" << w->log() << "\n";
    }
    workers_.clear();  // SIGKILL whatever still runs
    master_.reset();
    std::error_code ec;
    if (!HasFailure() && !std::getenv("RAYFARM_E2E_KEEP"))
      fs::remove_all(dir_, ec);  // kept for a look
  }

  std::string worker_endpoint() const { return "tcp://127.0.0.1:" + std::to_string(worker_port_); }
  std::string client_endpoint() const { return "tcp://127.0.0.1:" + std::to_string(client_port_); }
  const fs::path& dir() const { return dir_; }

  /// Starts the master (again, after a crash, with `log` another file: the log is appended to).
  void start_master(const std::string& log = "master.log") {
    master_ = std::make_unique<Process>(
        std::vector<std::string>{bin("master/rayfarm-master"), "--worker-endpoint",
                                 worker_endpoint(), "--client-endpoint", client_endpoint(),
                                 "--data-dir", (dir_ / "data").string(), "--heartbeat-ms", "200",
                                 "--liveness", "3", "--image-interval-ms", "500"},
        dir_ / log);
    ASSERT_TRUE(
        wait_until([&] { return master_->log().find("master listening") != std::string::npos; },
                   milliseconds{10000}))
        << "master did not start:\n"
        << master_->log();
  }

  Process& start_worker(const std::string& name, int threads = 1) {
    auto p = std::make_unique<Process>(
        std::vector<std::string>{
            bin("worker/rayfarm-worker"), "--master", worker_endpoint(), "--threads",
            std::to_string(threads), "--cache-dir", (dir_ / ("cache-" + name)).string(), "--name",
            name, "--heartbeat-ms", "200", "--liveness", "3", "--reconnect-max-ms", "1000"},
        dir_ / (name + ".log"));
    Process& ref = *p;
    workers_[name] = std::move(p);
    return ref;
  }

  Process& master() { return *master_; }

  /// Runs the CLI with `args` (and --master for farm commands) and waits for it.
  RunResult cli(std::vector<std::string> args, bool farm = true,
                milliseconds timeout = milliseconds{90000}) {
    static std::atomic<int> counter{0};
    const int n = counter++;
    std::vector<std::string> argv{bin("cli/rayfarm")};
    argv.insert(argv.end(), args.begin(), args.end());
    if (farm) {
      argv.push_back("--master");
      argv.push_back(client_endpoint());
    }
    const fs::path out = dir_ / ("cli-" + std::to_string(n) + ".out");
    const fs::path err = dir_ / ("cli-" + std::to_string(n) + ".err");
    Process p(argv, out, err);
    RunResult r;
    r.code = p.wait(timeout).value_or(-1);
    r.out = read_text(out);
    r.err = read_text(err);
    return r;
  }

  /// Copies a bundled scene (and its files) into the test folder with a smaller film.
  fs::path small_scene(const std::string& name, uint32_t size) {
    const fs::path from = fs::path(RAYFARM_SOURCE_DIR) / "scenes" / name;
    const fs::path to = dir_ / "scenes" / name;
    fs::create_directories(to);
    fs::copy(from, to, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
    nlohmann::json scene = nlohmann::json::parse(read_text(to / "scene.json"));
    scene["film"] = {{"width", size}, {"height", size}};
    std::ofstream(to / "scene.json") << scene.dump(2);
    return to / "scene.json";
  }

  /// `rayfarm render` of the same job on this machine, for reference.
  fs::path local_render(const fs::path& scene, const std::vector<std::string>& settings) {
    const fs::path out = dir_ / ("local-" + std::to_string(local_count_++) + ".exr");
    std::vector<std::string> args{"render", scene.string(), "-o", out.string(), "--threads", "2"};
    args.insert(args.end(), settings.begin(), settings.end());
    const RunResult r = cli(args, false);
    EXPECT_EQ(r.code, 0) << r.err;
    return out;
  }

  std::string submit(const fs::path& scene, const std::vector<std::string>& settings,
                     bool wait = false) {
    std::vector<std::string> args{"submit", scene.string()};
    args.insert(args.end(), settings.begin(), settings.end());
    if (wait) args.push_back("--wait");
    const RunResult r = cli(args);
    EXPECT_EQ(r.code, 0) << r.out << r.err;
    return r.out.substr(0, r.out.find('\n'));
  }

  fs::path fetch(const std::string& job) {
    const fs::path out = dir_ / (job + ".exr");
    const RunResult r = cli({"fetch", job, "-o", out.string()});
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir_ / (job + ".png")));
    return out;
  }

  wire::JobStatus status(const std::string& job) {
    RawPeer client(client_endpoint());
    wire::StatusRequest request;
    request.set_job_id(job);
    client.send(protocol::encode(request));
    return client.expect<wire::JobStatus>();
  }

  void wait_for_state(const std::string& job, wire::JobState state, seconds timeout = seconds{60}) {
    ASSERT_TRUE(wait_until([&] { return status(job).state() == state; }, timeout))
        << "job " << job << " never reached " << protocol::job_state_name(state);
  }

  void wait_for_units(const std::string& job, uint64_t units) {
    ASSERT_TRUE(wait_until([&] { return status(job).units_done() >= units; }, milliseconds{60000}));
  }

 private:
  fs::path dir_;
  int worker_port_ = 0, client_port_ = 0;
  int local_count_ = 0;
  std::unique_ptr<Process> master_;
  std::map<std::string, std::unique_ptr<Process>> workers_;
};

TEST_F(FarmTest, TwoWorkersRenderTheCornellBoxBitIdenticalToALocalRender) {
  start_master();
  Process& a = start_worker("wa", 2);  // two threads: two units at once
  Process& b = start_worker("wb");
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
  EXPECT_NE(master().log().find("left (stopped)"), std::string::npos);
  master().signal(SIGTERM);
  EXPECT_EQ(master().wait(milliseconds{10000}), std::optional<int>(0));
}

TEST_F(FarmTest, AWorkerKilledMidJobLosesNothing) {
  start_master();
  Process& victim = start_worker("victim");
  start_worker("survivor");
  const fs::path scene =
      small_scene("embree-cornell", 64);  // an OBJ and an MTL travel in the bundle
  const std::vector<std::string> settings{"--spp", "1024", "--seed", "3"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "32", "--pass-spp", "128"});  // 32 units
  const std::string job = submit(scene, job_settings);
  wait_for_units(job, 4);

  // Kill the victim while it holds a lease: stopped, both workers' units are leased.
  bool killed = false;
  for (int attempt = 0; attempt < 50 && !killed; ++attempt) {
    victim.signal(SIGSTOP);
    std::this_thread::sleep_for(milliseconds{30});
    if (status(job).units_leased() == 2) {
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
  EXPECT_TRUE(has_line(log, "requeued 1 unit of worker victim (", "): j0001 unit "))
      << "no requeue in the master log";
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
}

TEST_F(FarmTest, AWorkerThatJoinsLateTakesWork) {
  start_master();
  start_worker("early");
  const fs::path scene = small_scene("cornell-box", 64);
  const std::vector<std::string> settings{"--spp", "512", "--seed", "11"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "32", "--pass-spp", "32"});  // 64 units
  const std::string job = submit(scene, job_settings);
  wait_for_units(job, 4);
  Process& late = start_worker("late");
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
  start_master(
      "master-2.log");  // same ports, same data dir: the job is restarted from the beginning
  EXPECT_NE(master().log().find("job j0001 restarted from the beginning"), std::string::npos)
      << master().log();
  wait_for_units(job, 4);

  // A master away for longer than the liveness window: the worker reconnects with back-off.
  master().signal(SIGKILL);
  ASSERT_TRUE(master().wait(milliseconds{5000}));
  ASSERT_TRUE(wait_until([&] { return worker.log().find("is silent for") != std::string::npos; },
                         milliseconds{10000}));
  std::this_thread::sleep_for(milliseconds{1500});
  start_master("master-3.log");
  wait_for_state(job, wire::JOB_DONE);
  EXPECT_TRUE(has_line(master().log(), "worker steady (", ") joined"));
  EXPECT_EQ(count_of(worker.log(), "connected to the master"), 3u) << worker.log();
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
}

TEST_F(FarmTest, ADuplicateResultIsDroppedAndChangesNothing) {
  start_master();
  const fs::path scene = small_scene("cornell-box", 32);
  const std::vector<std::string> settings{"--spp", "16", "--seed", "5"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "16", "--pass-spp", "8"});  // 8 units
  const std::string job = submit(scene, job_settings);

  // A worker of our own that sends every result twice.
  RawPeer fake(worker_endpoint());
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
  start_master();
  for (const auto& [endpoint, role] : {std::pair{client_endpoint(), wire::ROLE_CLIENT},
                                       std::pair{worker_endpoint(), wire::ROLE_WORKER}}) {
    RawPeer peer(endpoint);
    wire::Hello hello;
    hello.set_role(role);
    hello.set_name("from-the-future");
    peer.send(protocol::encode(hello, protocol::kProtocolVersion + 1));
    const auto refusal = peer.expect<wire::Refusal>();
    EXPECT_EQ(refusal.master_version(), protocol::kProtocolVersion);
    EXPECT_EQ(refusal.peer_version(), protocol::kProtocolVersion + 1);
    EXPECT_NE(refusal.reason().find("version 1"), std::string::npos) << refusal.reason();
    EXPECT_NE(refusal.reason().find("version 2"), std::string::npos) << refusal.reason();
  }
  EXPECT_EQ(count_of(master().log(), "it speaks protocol version 2, this master 1"), 2u)
      << master().log();
  EXPECT_EQ(cli({"list"}).code, 0);
}

TEST_F(FarmTest, GarbageOnEitherSocketIsLoggedAndIgnored) {
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
  RawPeer client(client_endpoint());
  RawPeer worker(worker_endpoint());
  for (const auto& frames : garbage) {
    client.send(frames);
    worker.send(frames);
  }
  // The client socket answers each bad request with an error; the worker socket stays silent.
  for (size_t i = 0; i < garbage.size(); ++i) {
    const auto error = client.expect<wire::Error>();
    EXPECT_NE(error.message().find("cannot decode"), std::string::npos) << error.message();
  }
  EXPECT_TRUE(wait_until(
      [&] { return count_of(master().log(), "ignored a bad message") == 2 * garbage.size(); },
      milliseconds{5000}))
      << master().log();
  // A valid message on the wrong socket is refused by name.
  worker.send(protocol::encode(wire::ListJobs{}));
  EXPECT_NE(worker.expect<wire::Error>().message().find("unknown worker"), std::string::npos);

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
  RawPeer client(client_endpoint());
  wire::SubmitJob request;
  protocol::bundle_to_wire(make_bundle({{"scene.json", "{\"film\": {\"width\": -3}}"}}),
                           request.mutable_bundle());
  request.set_scene_path("scene.json");
  client.send(protocol::encode(request));
  const auto reply = client.expect<wire::SubmitReply>();
  EXPECT_TRUE(reply.job_id().empty());
  EXPECT_NE(reply.error().find("scene.json"), std::string::npos) << reply.error();
  EXPECT_EQ(reply.error().find(dir().string()), std::string::npos) << reply.error();

  // Cancelling a queued job (no workers) ends it, and submit --wait reports it.
  const fs::path scene = small_scene("furnace", 16);
  const std::string job = submit(scene, {"--spp", "4"});
  const RunResult cancelled = cli({"cancel", job});
  EXPECT_EQ(cancelled.code, 0);
  EXPECT_NE(cancelled.out.find("cancelled"), std::string::npos);
  EXPECT_EQ(cli({"watch", job}).code, 2);
}

}  // namespace
}  // namespace rayfarm::test

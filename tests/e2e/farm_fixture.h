#pragma once
// The fixture of the farm's end-to-end tests: a fresh folder, two loopback ports, a master and
// workers as real processes, the rayfarm CLI, raw peers for what the CLI never sends, and the
// checks every farm test makes (bit-identical images, log lines). How processes authenticate
// (CURVE keys or --insecure) is the derived fixture's choice. Every wait is bounded; every process
// is killed by PID when its test ends, passed or failed, and the logs of a failed test are printed.
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <set>

#include <nlohmann/json.hpp>

#include "common/image/exr.h"
#include "common/net/keys.h"
#include "common/net/socket.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "tests/e2e/process.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::test {

namespace fs = std::filesystem;
using std::chrono::seconds;
using testing::read_file;

/// An executable of the build, by its path relative to the build folder.
inline std::string bin(const std::string& relative) {
  return (fs::path(RAYFARM_BINARY_DIR) / relative).string();
}

/// True when some line of `text` holds `first` and, after it, `then`.
inline bool has_line(const std::string& text, const std::string& first, const std::string& then) {
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

/// CURVE keys for a test farm in `keys`: the master's pair (master.key, master.key_secret), each
/// peer's pair in own/ (NAME.key, NAME.key_secret), and each peer's public key in the allow-list
/// folder named beside it ("clients" or "workers").
inline void make_keys(const fs::path& keys,
                      const std::vector<std::pair<std::string, std::string>>& peers) {
  net::write_key_pair(keys, "master", net::generate_key_pair());
  for (const auto& [name, list] : peers) {
    net::write_key_pair(keys / "own", name, net::generate_key_pair());
    fs::create_directories(keys / list);
    fs::copy_file(keys / "own" / (name + ".key"), keys / list / (name + ".key"));
  }
}

/// Two images hold the same float bits in the same layout, and some light.
inline ::testing::AssertionResult bit_identical(const fs::path& a, const fs::path& b) {
  const Image x = read_exr(a), y = read_exr(b);
  if (x.width != y.width || x.height != y.height || x.rgb.size() != y.rgb.size()) {
    return ::testing::AssertionFailure() << "sizes differ: " << x.width << "x" << x.height << " vs "
                                         << y.width << "x" << y.height;
  }
  if (std::memcmp(x.rgb.data(), y.rgb.data(), x.rgb.size() * sizeof(float)) != 0) {
    size_t differing = 0;
    for (size_t i = 0; i < x.rgb.size(); ++i) differing += x.rgb[i] != y.rgb[i];
    return ::testing::AssertionFailure() << differing << " of " << x.rgb.size() << " values differ";
  }
  for (float v : x.rgb)
    if (v > 0.f) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "the image is black";
}

/// A raw DEALER peer speaking the codec, for what the CLI and the worker never send.
class RawPeer {
 public:
  explicit RawPeer(const std::string& endpoint, const net::Curve& curve = {})
      : socket_(endpoint, net::kDefaultMaxMessageBytes, curve) {}
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

struct RunResult {
  int code = -1;
  std::string out, err;
};

class FarmFixture : public ::testing::Test {
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
      for (const std::string& log : logs_)
        std::cerr << "---- " << log << " ----\n" << read_file(dir_ / log) << "\n";
    }
    workers_.clear();  // SIGKILL whatever still runs
    master_.reset();
    std::error_code ec;
    if (!HasFailure() && !std::getenv("RAYFARM_E2E_KEEP"))
      fs::remove_all(dir_, ec);  // kept for a look
  }

  /// The options that let the CLI and raw clients in: keys, or --insecure.
  virtual std::vector<std::string> client_auth() const = 0;
  virtual net::Curve client_curve() const = 0;

  std::string worker_endpoint() const { return "tcp://127.0.0.1:" + std::to_string(worker_port_); }
  std::string client_endpoint() const { return "tcp://127.0.0.1:" + std::to_string(client_port_); }
  const fs::path& dir() const { return dir_; }
  fs::path job_dir(const std::string& job) const { return dir_ / "data" / "jobs" / job; }

  /// Starts the master with `options` (endpoints and data dir added) logging to `log`; again after
  /// a crash with the same ports and data dir. Returns once it listens.
  void run_master(const std::string& log, const std::vector<std::string>& options) {
    std::vector<std::string> argv{bin("master/rayfarm-master"), "--worker-endpoint",
                                  worker_endpoint(),           "--client-endpoint",
                                  client_endpoint(),           "--data-dir",
                                  (dir_ / "data").string()};
    argv.insert(argv.end(), options.begin(), options.end());
    logs_.insert(log);
    master_ = std::make_unique<Process>(argv, dir_ / log);
    ASSERT_TRUE(
        wait_until([&] { return master_->log().find("master listening") != std::string::npos; },
                   milliseconds{10000}))
        << "master did not start:\n"
        << master_->log();
  }

  /// Starts a worker named `name` with `options` (master, cache and name added).
  Process& run_worker(const std::string& name, const std::vector<std::string>& options) {
    std::vector<std::string> argv{bin("worker/rayfarm-worker"),
                                  "--master",
                                  worker_endpoint(),
                                  "--cache-dir",
                                  (dir_ / ("cache-" + name)).string(),
                                  "--name",
                                  name};
    argv.insert(argv.end(), options.begin(), options.end());
    logs_.insert(name + ".log");
    auto p = std::make_unique<Process>(argv, dir_ / (name + ".log"));
    Process& ref = *p;
    workers_[name] = std::move(p);
    return ref;
  }

  Process& master() { return *master_; }

  /// Runs the CLI with `args` (and, for farm commands, --master and client_auth(), or `auth`
  /// instead) and waits for it.
  RunResult cli(std::vector<std::string> args, bool farm = true,
                milliseconds timeout = milliseconds{90000},
                std::optional<std::vector<std::string>> auth = std::nullopt) {
    static std::atomic<int> counter{0};
    const int n = counter++;
    std::vector<std::string> argv{bin("cli/rayfarm")};
    argv.insert(argv.end(), args.begin(), args.end());
    if (farm) {
      argv.push_back("--master");
      argv.push_back(client_endpoint());
      if (!auth) auth = client_auth();
      argv.insert(argv.end(), auth->begin(), auth->end());
    }
    const fs::path out = dir_ / ("cli-" + std::to_string(n) + ".out");
    const fs::path err = dir_ / ("cli-" + std::to_string(n) + ".err");
    Process p(argv, out, err);
    RunResult r;
    r.code = p.wait(timeout).value_or(-1);
    r.out = read_file(out);
    r.err = read_file(err);
    return r;
  }

  /// Copies a bundled scene (and its files) into the test folder with a smaller film.
  fs::path small_scene(const std::string& name, uint32_t size, const std::string& filter = "") {
    const fs::path from = fs::path(RAYFARM_SOURCE_DIR) / "scenes" / name;
    const fs::path to = dir_ / "scenes" / name;
    fs::create_directories(to);
    fs::copy(from, to, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
    nlohmann::json scene = nlohmann::json::parse(read_file(to / "scene.json"));
    scene["film"] = {{"width", size}, {"height", size}};
    if (!filter.empty()) scene["film"]["filter"] = filter;
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

  /// Submits a job; its id.
  std::string submit(const fs::path& scene, const std::vector<std::string>& settings,
                     bool wait = false) {
    std::vector<std::string> args{"submit", scene.string()};
    args.insert(args.end(), settings.begin(), settings.end());
    if (wait) args.push_back("--wait");
    const RunResult r = cli(args);
    EXPECT_EQ(r.code, 0) << r.out << r.err;
    return r.out.substr(0, r.out.find('\n'));
  }

  /// The job's image through `rayfarm fetch` (which writes a PNG beside it).
  fs::path fetch(const std::string& job) {
    const fs::path out = dir_ / (job + ".exr");
    const RunResult r = cli({"fetch", job, "-o", out.string()});
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir_ / (job + ".png")));
    return out;
  }

  wire::JobStatus status(const std::string& job) {
    RawPeer client(client_endpoint(), client_curve());
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
    ASSERT_TRUE(wait_until([&] { return status(job).units_done() >= units; }, milliseconds{60000}))
        << "job " << job << " never merged " << units << " units";
  }

 private:
  fs::path dir_;
  int worker_port_ = 0, client_port_ = 0;
  int local_count_ = 0;
  std::unique_ptr<Process> master_;
  std::map<std::string, std::unique_ptr<Process>> workers_;
  std::set<std::string> logs_;
};

/// A farm with CURVE keys made in SetUp under keys(): the master's, the CLI's client key "cli" and
/// the worker key "w1", both in the master's allow-lists.
class KeyedFarmFixture : public FarmFixture {
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
  /// The master's key options: its key and both allow-lists.
  std::vector<std::string> master_keys() const {
    return {"--key",         (keys() / "master.key_secret").string(),
            "--worker-keys", (keys() / "workers").string(),
            "--client-keys", (keys() / "clients").string()};
  }
  /// Worker w1's key options.
  std::vector<std::string> worker_keys() const {
    return {"--key", (keys() / "own" / "w1.key_secret").string(), "--master-key",
            (keys() / "master.key").string()};
  }

 private:
  net::KeyPair client_keys_;
  std::string master_public_;
};

}  // namespace rayfarm::test

// What a peer holding a valid key can make the master do, and what a failing disk does to a job.
// Results merge only from the connection that was leased the unit, and only when their sums could
// come from its samples; failures count per key and only for units held, so that one key can
// block only itself; jobs belong to the key that submitted them; a reference's header is checked
// before its pixels are allocated; per-connection queues are bounded; complaints about garbage are
// rate-limited; a job is done only once its final image and record are on disk.
#include <gtest/gtest.h>

#include <spdlog/sinks/ostream_sink.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <thread>

#include <zmq.hpp>

#include "common/image/exr.h"
#include "common/net/zap.h"
#include "common/protocol/codec.h"
#include "common/util/atomic_file.h"
#include "common/util/log.h"
#include "master/broker.h"
#include "master/job_manager.h"
#include "master/log_budget.h"
#include "master/metrics.h"
#include "tests/master/broker_peer.h"
#include "tests/master/job_requests.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {
namespace fs = std::filesystem;
using std::chrono::milliseconds;
using test_jobs::furnace_job;
using test_jobs::result_for;
using testing::TempDir;

wire::UnitFailed failure_of(const wire::WorkUnit& unit, const std::string& why) {
  wire::UnitFailed f;
  f.set_job_id(unit.job_id());
  f.set_unit_id(unit.unit_id());
  f.set_reason(why);
  return f;
}

// ---------------------------------------------------------------------------------------------
// Results and failures, without sockets

/// Checkpoints at every completed round of passes (and at shutdown) only: the tests of a full
/// disk stop the disk right after the first round's checkpoint.
JobManagerOptions round_checkpoints() {
  JobManagerOptions o;
  o.checkpoint_interval = std::chrono::milliseconds{0};
  return o;
}

class PeerTrustTest : public ::testing::Test {
 protected:
  TempDir dir;
  JobStore store{dir.path() / "data"};
  JobManager jobs{store, round_checkpoints()};
};

TEST_F(PeerTrustTest, AResultCountsOnlyFromTheConnectionThatWasLeasedTheUnit) {
  const std::string id = jobs.submit(furnace_job(4, 16, 4));  // 4 units
  const auto unit = jobs.next_unit("w1", "k1");
  ASSERT_TRUE(unit);
  // Another connection, even with the same key, and a unit leased to nobody: dropped, and
  // neither counts as a failure of anyone.
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(jobs.on_result("forger", result_for(*unit, 9.0), "k1"), MergeOutcome::kUnleased);
  }
  wire::WorkUnit other = *unit;
  other.set_unit_id(unit->unit_id() + 1);
  other.mutable_tile()->set_x0(16);
  other.mutable_tile()->set_x1(32);
  EXPECT_EQ(jobs.on_result("w1", result_for(other), "k1"), MergeOutcome::kUnleased);
  EXPECT_EQ(jobs.status(id, 1)->units_done(), 0u);
  EXPECT_EQ(jobs.status(id, 1)->state(), wire::JOB_RUNNING);
  // The holder's result merges; the forger's value never reached the film.
  EXPECT_EQ(jobs.on_result("w1", result_for(*unit), "k1"), MergeOutcome::kMerged);
  EXPECT_EQ(jobs.on_result("forger", result_for(*unit, 9.0), "k1"), MergeOutcome::kDuplicate);
  while (auto u = jobs.next_unit("w1", "k1")) jobs.on_result("w1", result_for(*u), "k1");
  ASSERT_EQ(jobs.status(id, 1)->state(), wire::JOB_DONE);
  const Image image = read_exr(dir.path() / "data" / "jobs" / id / "image.exr");
  for (float v : image.rgb) ASSERT_EQ(v, 0.5f);
}

TEST_F(PeerTrustTest, ImpossibleSumsAreRejectedAndCountAgainstTheSender) {
  const std::string id = jobs.submit(furnace_job(4, 16, 4));
  const auto unit = jobs.next_unit("w1", "k1");
  ASSERT_TRUE(unit);
  const uint32_t n = unit->sample_end() - unit->sample_begin();
  auto tampered = [&](auto change) {
    TileResult r = protocol::result_from_wire(result_for(*unit));
    change(r);
    return protocol::result_to_wire(unit->job_id(), unit->unit_id(), r, 0.01);
  };
  const std::vector<std::pair<const char*, wire::UnitResult>> bad{
      {"negative sum of squares", tampered([](TileResult& r) { r.sum_sq[7] = -1; })},
      {"sum larger than its samples can reach",
       tampered([&](TileResult& r) { r.sum[0] = to_fixed(kMaxSampleValue) * (n + 1); })},
      {"sum^2 > n * sum of squares", tampered([](TileResult& r) { r.sum_sq[3] = 0; })},
      {"non-finite samples", tampered([&](TileResult& r) { r.nonfinite = uint64_t{n} * 256 + 1; })},
  };
  for (const auto& [what, result] : bad) {
    // The unit goes back to the queue each time; w1 held it, so its next result is looked at.
    EXPECT_EQ(jobs.on_result("w1", result, "k1"), MergeOutcome::kRejected) << what;
  }
  EXPECT_EQ(jobs.status(id, 1)->units_done(), 0u);
  // Three rejections blocked key k1 from the job; the job itself goes on.
  EXPECT_EQ(jobs.status(id, 1)->state(), wire::JOB_RUNNING);
  EXPECT_FALSE(jobs.next_unit("w2", "k1")) << "another connection of a blocked key";
  EXPECT_TRUE(jobs.next_unit("w3", "k2"));
}

TEST_F(PeerTrustTest, ALateResultOfACancelledJobIsDiscardedNotRejected) {
  // Cancelling a job with units out is routine: their results come back and are dropped, and
  // count as neither a wrong result nor a failure of their sender.
  const std::string id = jobs.submit(furnace_job(4, 16, 4));  // 4 units
  std::vector<wire::WorkUnit> out;
  for (int i = 0; i < 4; ++i) {
    auto unit = jobs.next_unit("w" + std::to_string(i), "k1");
    ASSERT_TRUE(unit);
    out.push_back(*unit);
  }
  ASSERT_EQ(jobs.cancel(id), wire::JOB_CANCELLED);
  for (size_t i = 0; i < out.size(); ++i) {
    EXPECT_EQ(jobs.on_result("w" + std::to_string(i), result_for(out[i]), "k1"),
              MergeOutcome::kDiscarded);
  }
  // A retry starts over: key k1 was not blocked by the four.
  ASSERT_EQ(jobs.retry(id), wire::JOB_QUEUED);
  EXPECT_TRUE(jobs.next_unit("w9", "k1"));
}

// ---------------------------------------------------------------------------------------------
// Log budgets

TEST(LogBudgetTest, EveryKindHasOneBudgetAndAFloodOfItIsCutToItsBurst) {
  using Clock = LogBudget::Clock;
  // The table lists every kind once.
  std::set<PeerLog> kinds;
  for (const LogBudgetSpec& s : kLogBudgets) {
    EXPECT_TRUE(kinds.insert(s.kind).second) << s.name << " is listed twice";
    EXPECT_GE(s.burst, 1.0) << s.name;
    EXPECT_GT(s.interval_s, 0.0) << s.name;
  }
  EXPECT_EQ(kinds.size(), static_cast<size_t>(PeerLog::kForbidden) + 1) << "a kind has no budget";

  for (const LogBudgetSpec& s : kLogBudgets) {
    LogBudget budget;
    const Clock::time_point t0{};
    const uint64_t flood = 5000;
    uint64_t logged = 0;
    for (uint64_t i = 0; i < flood; ++i) logged += budget.take(s.kind, "key mallory", t0).log;
    EXPECT_EQ(logged, static_cast<uint64_t>(s.burst)) << s.name;
    // Another key, and another kind of the same key, have budgets of their own.
    EXPECT_TRUE(budget.take(s.kind, "key alice", t0).log) << s.name;
    // Once one line's worth of time has passed, the next line says how many were held back.
    const auto later = t0 + std::chrono::duration_cast<Clock::duration>(
                                std::chrono::duration<double>(s.interval_s * 1.01));
    const LogBudget::Verdict reopened = budget.take(s.kind, "key mallory", later);
    ASSERT_TRUE(reopened.log) << s.name;
    EXPECT_EQ(reopened.suppressed, flood - logged) << s.name;
    EXPECT_NE(reopened.suffix().find(fmt::format("({} similar lines suppressed in the last {:.1f} s)",
                                                 flood - logged, s.interval_s * 1.01)),
              std::string::npos)
        << s.name << ": " << reopened.suffix();
    EXPECT_FALSE(budget.take(s.kind, "key mallory", later).log) << s.name << ": one line's worth";
    // The count starts over after the line that reported it.
    const LogBudget::Verdict next = budget.take(
        s.kind, "key mallory",
        later + std::chrono::duration_cast<Clock::duration>(
                    std::chrono::duration<double>(s.interval_s * 1.01)));
    EXPECT_TRUE(next.log) << s.name;
    EXPECT_EQ(next.suppressed, 1u) << s.name;
  }
}

TEST(ImplausibleTest, NamesThePixelAndAcceptsTheExtremesSamplesCanReach) {
  // Samples at the largest magnitude a sample may have, and a mix of signs, are plausible.
  TileResult r(TileRect{0, 0, 2, 2}, SampleRange{0, 4});
  const double v = kMaxSampleValue;
  for (size_t i = 0; i < r.sum.size(); ++i) {
    r.sum[i] = to_fixed(v) * 3 + to_fixed(-v);  // samples v, v, v, -v
    r.sum_sq[i] = to_fixed(v * v) * 4;
  }
  r.nonfinite = 16;
  EXPECT_EQ(implausible(r), "");
  r.sum[5] = to_fixed(v) * 5;  // more than four samples can add up to
  EXPECT_NE(implausible(r).find("pixel (1, 0) channel 2 has a sum larger"), std::string::npos)
      << implausible(r);
  r.sum[5] = to_fixed(v) * 4;
  r.sum_sq[5] = to_fixed(v * v) * 2;  // four samples of magnitude v cannot square to 2 v^2
  EXPECT_NE(implausible(r).find("sum^2 > n * sum of squares"), std::string::npos) << implausible(r);
  r.sum_sq[5] = to_fixed(v * v) * 4;
  r.nonfinite = 17;
  EXPECT_NE(implausible(r).find("17 non-finite samples of the 16"), std::string::npos);
}

TEST_F(PeerTrustTest, FailuresCountPerKeyAndOnlyForUnitsTheConnectionHolds) {
  const std::string id = jobs.submit(furnace_job(4, 16, 4));  // 4 units
  const auto held = jobs.next_unit("w1", "k1");
  ASSERT_TRUE(held);
  // Reports of failures of a unit the sender does not hold change nothing.
  for (const std::string conn : {"x1", "x2", "x3", "x4"}) {
    EXPECT_FALSE(jobs.on_unit_failed(conn, failure_of(*held, "forged"), conn));
  }
  EXPECT_EQ(jobs.status(id, 0)->state(), wire::JOB_RUNNING);
  // Three connections of one key each fail the unit they hold: one key is one worker, so the
  // key is blocked and the job goes on.
  EXPECT_TRUE(jobs.on_unit_failed("w1", failure_of(*held, "out of memory"), "k1"));
  for (const std::string conn : {"w2", "w3"}) {
    const auto unit = jobs.next_unit(conn, "k1");
    ASSERT_TRUE(unit);
    EXPECT_EQ(unit->unit_id(), held->unit_id());
    EXPECT_TRUE(jobs.on_unit_failed(conn, failure_of(*unit, "out of memory"), "k1"));
  }
  EXPECT_EQ(jobs.status(id, 0)->state(), wire::JOB_RUNNING);
  EXPECT_FALSE(jobs.next_unit("w9", "k1")) << "k1 is blocked from the job";
  // The same unit failing under two more keys makes three different workers: the job fails.
  for (const std::string key : {"k2", "k3"}) {
    const auto unit = jobs.next_unit("c-" + key, key);
    ASSERT_TRUE(unit);
    EXPECT_EQ(unit->unit_id(), held->unit_id());
    jobs.on_unit_failed("c-" + key, failure_of(*unit, "out of memory"), key);
  }
  const auto st = jobs.status(id, 0);
  EXPECT_EQ(st->state(), wire::JOB_FAILED);
  EXPECT_NE(st->error().find("failed on 3 different workers"), std::string::npos) << st->error();
  EXPECT_NE(st->error().find("key 'k2'"), std::string::npos) << st->error();
}

TEST_F(PeerTrustTest, AJobEveryConnectedWorkerIsBlockedFromFails) {
  // One key shared by every worker of the farm (as compose does): blocking it leaves nobody to
  // render the job, which then fails instead of waiting forever.
  JobManagerOptions o;
  std::vector<std::string> connected{"shared"};
  o.connected_workers = [&] { return connected; };
  o.blocked_grace = milliseconds{0};  // a worker that joins within the grace would save the job
  JobManager farm(store, o);
  const std::string id = farm.submit(furnace_job(4, 16, 4));
  for (const std::string conn : {"w1", "w2", "w3"}) {
    const auto unit = farm.next_unit(conn, "shared");
    ASSERT_TRUE(unit);
    farm.on_unit_failed(conn, failure_of(*unit, "cannot load the scene"), "shared");
  }
  farm.tick();
  const auto st = farm.status(id, 3);
  EXPECT_EQ(st->state(), wire::JOB_FAILED);
  EXPECT_NE(st->error().find("every connected worker (1) has been blocked"), std::string::npos)
      << st->error();
  EXPECT_NE(st->error().find("cannot load the scene"), std::string::npos) << st->error();
  // With another key connected, the job waits for it instead.
  connected = {"shared", "other"};
  const std::string next = farm.submit(furnace_job(4, 16, 4));
  for (const std::string conn : {"w1", "w2", "w3"}) {
    const auto unit = farm.next_unit(conn, "shared");
    ASSERT_TRUE(unit);
    farm.on_unit_failed(conn, failure_of(*unit, "cannot load the scene"), "shared");
  }
  farm.tick();
  EXPECT_EQ(farm.status(next, 3)->state(), wire::JOB_RUNNING);
  EXPECT_TRUE(farm.next_unit("w4", "other"));
}

TEST(KeyNames, AKeyIsNamedByItsFileNotByTheNameItsHolderWroteInIt) {
  // Names decide who owns a job and who is an admin: they are the operator's, not the holder's.
  TempDir dir;
  const net::KeyPair keys = net::generate_key_pair();
  const net::KeyFiles files = net::write_key_pair(dir.path() / "made", "admin", keys);
  fs::create_directories(dir.path() / "clients");
  fs::copy_file(files.public_file, dir.path() / "clients" / "bob.key");
  const net::AllowList list = net::AllowList::load(dir.path() / "clients");
  ASSERT_NE(list.find(keys.public_key), nullptr);
  EXPECT_EQ(*list.find(keys.public_key), "bob");
}

/// `exr` with the data and display windows of its header rewritten to w x h.
std::string claim_size(std::string exr, int32_t w, int32_t h) {
  for (const char* name : {"dataWindow", "displayWindow"}) {
    const std::string tag = std::string(name) + '\0' + "box2i" + '\0';
    const size_t at = exr.find(tag);
    if (at == std::string::npos) return {};
    const int32_t box[4] = {0, 0, w - 1, h - 1};
    std::memcpy(exr.data() + at + tag.size() + 4, box, sizeof box);
  }
  return exr;
}

TEST_F(PeerTrustTest, AReferenceHeaderIsCheckedBeforeItsPixelsAreAllocated) {
  Image small;
  small.width = small.height = 32;
  small.rgb.assign(32 * 32 * 3, 0.5f);
  write_exr(dir.path() / "ref.exr", small);
  const std::string real = testing::read_file(dir.path() / "ref.exr");
  // A header that claims 16384 x 16384 (three gigabytes of float pixels), in a file of a few
  // kilobytes: refused from the header alone.
  const std::string huge = claim_size(real, 16384, 16384);
  ASSERT_FALSE(huge.empty());
  wire::SubmitJob request = furnace_job(4, 16, 4);
  request.set_reference_exr(huge);
  try {
    jobs.submit(request);
    FAIL() << "accepted a reference whose header claims 16384x16384";
  } catch (const JobRejected& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("its header says 16384x16384, the image is 32x32"), std::string::npos)
        << what;
    EXPECT_EQ(what.find(dir.path().string()), std::string::npos) << what;
  }
  request.set_reference_exr(real);
  EXPECT_NO_THROW(jobs.submit(request));
}

// ---------------------------------------------------------------------------------------------
// A full disk

/// While alive, every write into `dir` fails with `error` (ENOSPC by default).
class DiskFault {
 public:
  explicit DiskFault(const fs::path& dir, int error = ENOSPC) {
    set_write_fault_for_testing([prefix = dir.string(), error](const fs::path& path) {
      return path.string().rfind(prefix, 0) == 0 ? error : 0;
    });
  }
  ~DiskFault() { set_write_fault_for_testing({}); }
  DiskFault(const DiskFault&) = delete;
  DiskFault& operator=(const DiskFault&) = delete;
};

/// Renders job `id` of `jobs` to the end with constant results, as one worker.
void render_all(JobManager& jobs) {
  while (auto unit = jobs.next_unit("w", "k")) {
    ASSERT_EQ(jobs.on_result("w", result_for(*unit, 0.25 + 0.01 * unit->unit_id()), "k"),
              MergeOutcome::kMerged);
  }
}

/// The image of a job rendered with no fault, for comparison.
Image undisturbed_image(const fs::path& dir) {
  JobStore store(dir);
  JobManager jobs(store);
  const std::string id = jobs.submit(furnace_job(8, 16, 4));
  render_all(jobs);
  return read_exr(dir / "jobs" / id / "image.exr");
}

/// Leases and merges the units of the first round of passes (4 tiles), then waits for its
/// checkpoint to be on disk.
void render_first_round(JobManager& jobs) {
  for (int i = 0; i < 4; ++i) {
    const auto unit = jobs.next_unit("w", "k");
    ASSERT_TRUE(unit);
    ASSERT_EQ(unit->pass(), 0u);
    jobs.on_result("w", result_for(*unit, 0.25 + 0.01 * unit->unit_id()), "k");
  }
  jobs.wait_for_checkpoints();
}

TEST_F(PeerTrustTest, AFullDiskKeepsAFinishedJobRunningUntilItsImageAndRecordAreStored) {
  const std::string id = jobs.submit(furnace_job(8, 16, 4));  // 4 tiles x 2 passes
  render_first_round(jobs);
  const fs::path job_dir = dir.path() / "data" / "jobs" / id;
  ASSERT_TRUE(fs::exists(job_dir / "checkpoint-0.bin"));
  {
    DiskFault full(dir.path() / "data");
    render_all(jobs);  // the last units: the job's work is over
    auto st = jobs.status(id, 1);
    EXPECT_EQ(st->state(), wire::JOB_RUNNING) << "reported finished with its image not on disk";
    EXPECT_NE(st->storage_error().find("No space left on device"), std::string::npos)
        << st->storage_error();
    EXPECT_EQ(st->storage_error().find(dir.path().string()), std::string::npos)
        << "a client is shown the master's paths: " << st->storage_error();
    EXPECT_TRUE(fs::exists(job_dir / "checkpoint-0.bin")) << "its checkpoint was given up";
    EXPECT_EQ(jobs.image(id).state(), wire::JOB_RUNNING);
    // A submission now is refused for what it is.
    try {
      jobs.submit(furnace_job(8, 16, 4));
      FAIL() << "accepted a job it cannot store";
    } catch (const JobRejected& e) {
      EXPECT_EQ(std::string(e.what()),
                "the master cannot store the job: no space left on device (the master's data "
                "dir)");
    }
    jobs.tick();  // retrying while the disk is still full changes nothing
    EXPECT_EQ(jobs.status(id, 1)->state(), wire::JOB_RUNNING);
  }
  // The disk has room again: within the back-off the job is done, and its image is the one an
  // undisturbed render makes.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds{20};
  while (jobs.status(id, 1)->state() != wire::JOB_DONE &&
         std::chrono::steady_clock::now() < deadline) {
    jobs.tick();
    std::this_thread::sleep_for(milliseconds{50});
  }
  const auto st = jobs.status(id, 1);
  ASSERT_EQ(st->state(), wire::JOB_DONE);
  EXPECT_EQ(st->storage_error(), "");
  const Image image = read_exr(job_dir / "image.exr");
  const Image expected = undisturbed_image(dir.path() / "clean");
  EXPECT_EQ(image.rgb, expected.rgb);
  EXPECT_EQ(image.extra, expected.extra);
  EXPECT_EQ(image.attributes.at("rayfarm:spp"), "8");
}

TEST_F(PeerTrustTest, AMasterRestartedWhileTheDiskIsFullResumesFromItsLastCheckpoint) {
  const fs::path data = dir.path() / "data2";
  std::string id;
  {
    JobStore store2(data);
    JobManager first(store2, round_checkpoints());
    id = first.submit(furnace_job(8, 16, 4));
    render_first_round(first);
    DiskFault full(data);
    render_all(first);
    ASSERT_EQ(first.status(id, 1)->state(), wire::JOB_RUNNING);
    first.wait_for_checkpoints();  // its last checkpoint failed too
  }
  // Restarted on the same data dir with room again: the units merged after the checkpoint are
  // rendered again, nothing before it.
  JobStore store2(data);
  JobManager second(store2);
  second.recover();
  EXPECT_EQ(second.status(id, 1)->units_done(), 4u);
  std::vector<uint32_t> passes;
  while (auto unit = second.next_unit("w", "k")) {
    passes.push_back(unit->pass());
    second.on_result("w", result_for(*unit, 0.25 + 0.01 * unit->unit_id()), "k");
  }
  EXPECT_EQ(passes, (std::vector<uint32_t>{1, 1, 1, 1}));
  ASSERT_EQ(second.status(id, 1)->state(), wire::JOB_DONE);
  EXPECT_EQ(read_exr(data / "jobs" / id / "image.exr").rgb,
            undisturbed_image(dir.path() / "clean").rgb);
}

// ---------------------------------------------------------------------------------------------
// Through the broker, with real sockets

class BrokerTrustTest : public ::testing::Test {
 protected:
  TempDir dir;
  net::KeyPair master_keys = net::generate_key_pair();
  net::KeyPair worker_keys = net::generate_key_pair();
  std::map<std::string, net::KeyPair> clients{{"alice", net::generate_key_pair()},
                                              {"bob", net::generate_key_pair()},
                                              {"boss", net::generate_key_pair()}};

  MasterOptions options() {
    net::write_key_pair(dir.path() / "workers", "w1", worker_keys);
    for (const auto& [name, keys] : clients)
      net::write_key_pair(dir.path() / "clients", name, keys);
    MasterOptions o;
    o.worker_endpoint = "tcp://127.0.0.1:0";
    o.client_endpoint = "tcp://127.0.0.1:0";
    o.data_dir = dir.path() / "data";
    o.security.key = master_keys;
    o.security.worker_keys = dir.path() / "workers";
    o.security.client_keys = dir.path() / "clients";
    o.security.admin_clients = {"boss"};
    return o;
  }

  net::Dealer connect(const std::string& endpoint, const net::KeyPair& keys) const {
    return net::Dealer(endpoint, net::kDefaultMaxMessageBytes,
                       {keys.public_key, keys.secret_key, master_keys.public_key, ""});
  }
};

using test_peer::next;

/// Sends `request` and returns the reply, or fails the test.
template <class Message>
protocol::Decoded ask(net::Dealer& d, Message request) {
  EXPECT_TRUE(d.send(protocol::encode(std::move(request))));
  auto reply = next(d);
  EXPECT_TRUE(reply) << "no reply";
  return reply ? std::move(*reply) : protocol::Decoded{};
}

using test_peer::hello;

/// A broker running on its own thread for the life of the object.
struct Running {
  Broker broker;
  std::atomic<bool> stop{false};
  std::thread reactor;
  explicit Running(MasterOptions o) : broker(std::move(o)), reactor([this] { broker.run(stop); }) {}
  ~Running() {
    stop = true;
    reactor.join();
  }
};

std::string submit_as(net::Dealer& client) {
  const auto reply = ask(client, furnace_job(8, 16, 4));
  const auto* out = reply.as<wire::SubmitReply>();
  EXPECT_TRUE(out && !out->job_id().empty()) << (out ? out->error() : reply.type);
  return out ? out->job_id() : "";
}

TEST_F(BrokerTrustTest, OnlyTheOwnerOrAnAdminMayCancelAJob) {
  Running master(options());
  auto alice = connect(master.broker.client_endpoint(), clients["alice"]);
  auto bob = connect(master.broker.client_endpoint(), clients["bob"]);
  auto boss = connect(master.broker.client_endpoint(), clients["boss"]);
  const std::string id = submit_as(alice);

  // Bob sees it (jobs are not private by default), with its owner, but may not cancel it.
  auto list = ask(bob, wire::ListJobs{});
  ASSERT_TRUE(list.as<wire::JobList>());
  ASSERT_EQ(list.as<wire::JobList>()->jobs_size(), 1);
  EXPECT_EQ(list.as<wire::JobList>()->jobs(0).owner(), "alice");
  wire::CancelJob cancel;
  cancel.set_job_id(id);
  auto refused = ask(bob, cancel);
  ASSERT_TRUE(refused.as<wire::Error>()) << refused.type;
  EXPECT_NE(refused.as<wire::Error>()->message().find("belongs to key 'alice'"), std::string::npos)
      << refused.as<wire::Error>()->message();
  wire::StatusRequest status;
  status.set_job_id(id);
  EXPECT_EQ(ask(bob, status).as<wire::JobStatus>()->state(), wire::JOB_QUEUED);
  // An admin may.
  auto done = ask(boss, cancel);
  ASSERT_TRUE(done.as<wire::CancelReply>()) << done.type;
  EXPECT_EQ(done.as<wire::CancelReply>()->state(), wire::JOB_CANCELLED);
  // And so may the owner, of her next job.
  const std::string second = submit_as(alice);
  cancel.set_job_id(second);
  EXPECT_TRUE(ask(alice, cancel).as<wire::CancelReply>());
}

TEST_F(BrokerTrustTest, PrivateJobsAreInvisibleToOtherKeys) {
  MasterOptions o = options();
  o.security.private_jobs = true;
  Running master(std::move(o));
  auto alice = connect(master.broker.client_endpoint(), clients["alice"]);
  auto bob = connect(master.broker.client_endpoint(), clients["bob"]);
  auto boss = connect(master.broker.client_endpoint(), clients["boss"]);
  const std::string id = submit_as(alice);
  EXPECT_EQ(ask(bob, wire::ListJobs{}).as<wire::JobList>()->jobs_size(), 0);
  EXPECT_EQ(ask(alice, wire::ListJobs{}).as<wire::JobList>()->jobs_size(), 1);
  EXPECT_EQ(ask(boss, wire::ListJobs{}).as<wire::JobList>()->jobs_size(), 1);
  wire::StatusRequest status;
  status.set_job_id(id);
  auto hidden = ask(bob, status);
  ASSERT_TRUE(hidden.as<wire::Error>()) << hidden.type;
  EXPECT_NE(hidden.as<wire::Error>()->message().find("unknown job"), std::string::npos);
  wire::FetchImage fetch;
  fetch.set_job_id(id);
  EXPECT_TRUE(ask(bob, fetch).as<wire::Error>());
  wire::CancelJob cancel;
  cancel.set_job_id(id);
  EXPECT_TRUE(ask(bob, cancel).as<wire::Error>());
  EXPECT_EQ(ask(alice, status).as<wire::JobStatus>()->state(), wire::JOB_QUEUED);
}

TEST_F(BrokerTrustTest, AnotherConnectionCannotReturnOrFailAUnitItWasNotLeased) {
  Running master(options());
  auto alice = connect(master.broker.client_endpoint(), clients["alice"]);
  const std::string id = submit_as(alice);
  auto worker = connect(master.broker.worker_endpoint(), worker_keys);
  ASSERT_TRUE(ask(worker, hello(wire::ROLE_WORKER)).as<wire::Welcome>());
  auto work = ask(worker, wire::WorkRequest{});
  ASSERT_TRUE(work.as<wire::WorkUnit>()) << work.type;
  const wire::WorkUnit unit = *work.as<wire::WorkUnit>();

  // A second connection with the same valid key, which never said hello: its result for the
  // leased unit and its failure reports are dropped, and the job neither changes nor fails.
  auto forger = connect(master.broker.worker_endpoint(), worker_keys);
  for (int i = 0; i < 3; ++i) {
    forger.send(protocol::encode(result_for(unit, 1e6)));
    forger.send(protocol::encode(failure_of(unit, "forged")));
  }
  for (int i = 0; i < 3; ++i) {
    auto forger_i = connect(master.broker.worker_endpoint(), worker_keys);
    forger_i.send(protocol::encode(failure_of(unit, "forged")));
    next(forger_i, milliseconds{300});
  }
  next(forger, milliseconds{300});
  wire::StatusRequest status;
  status.set_job_id(id);
  auto st = ask(alice, status);
  ASSERT_TRUE(st.as<wire::JobStatus>());
  EXPECT_EQ(st.as<wire::JobStatus>()->state(), wire::JOB_RUNNING);
  EXPECT_EQ(st.as<wire::JobStatus>()->units_done(), 0u);
  // The real holder's result is merged.
  worker.send(protocol::encode(result_for(unit)));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds{5};
  uint64_t done = 0;
  while (done == 0 && std::chrono::steady_clock::now() < deadline) {
    done = ask(alice, status).as<wire::JobStatus>()->units_done();
  }
  EXPECT_EQ(done, 1u);
}

TEST_F(BrokerTrustTest, ABundleIsNotSentTwiceToOneConnectionWithinAMinute) {
  Running master(options());
  auto alice = connect(master.broker.client_endpoint(), clients["alice"]);
  submit_as(alice);
  auto worker = connect(master.broker.worker_endpoint(), worker_keys);
  ASSERT_TRUE(ask(worker, hello(wire::ROLE_WORKER)).as<wire::Welcome>());
  auto work = ask(worker, wire::WorkRequest{});
  ASSERT_TRUE(work.as<wire::WorkUnit>());
  wire::BundleRequest request;
  request.set_hash(work.as<wire::WorkUnit>()->bundle_hash());
  auto first = ask(worker, request);
  ASSERT_TRUE(first.as<wire::BundleReply>());
  EXPECT_EQ(first.as<wire::BundleReply>()->error(), "");
  EXPECT_GT(first.as<wire::BundleReply>()->bundle().files_size(), 0);
  for (int i = 0; i < 20; ++i) worker.send(protocol::encode(request));
  int refused = 0;
  while (auto again = next(worker, milliseconds{500})) {
    const auto* reply = again->as<wire::BundleReply>();
    ASSERT_TRUE(reply) << again->type;
    EXPECT_EQ(reply->bundle().files_size(), 0) << "a bundle was queued again";
    EXPECT_NE(reply->error().find("less than a minute ago"), std::string::npos) << reply->error();
    EXPECT_GT(reply->retry_after_ms(), 0u) << "a worker must ask again, not fail its units";
    ++refused;
  }
  EXPECT_EQ(refused, 20);
}

TEST_F(BrokerTrustTest, GarbageIsLoggedOncePerIntervalNotOncePerMessage) {
  std::ostringstream captured;
  auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(captured);
  auto logger = get_logger("master");
  logger->sinks().push_back(sink);
  {
    Running master(options());
    auto bob = connect(master.broker.client_endpoint(), clients["bob"]);
    for (int i = 0; i < 500; ++i) bob.send(net::Frames{"garbage", "\x01\x02"});
    // The master has read all of it once it answers a request sent after it (replies past the
    // client's queue bound are dropped, so ask until one gets through).
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds{10};
    bool listed = false;
    while (!listed && std::chrono::steady_clock::now() < deadline) {
      bob.send(protocol::encode(wire::ListJobs{}));
      while (auto m = next(bob, milliseconds{200})) listed |= m->as<wire::JobList>() != nullptr;
    }
    EXPECT_TRUE(listed);
  }
  logger->sinks().pop_back();
  const std::string log = captured.str();
  size_t lines = 0;
  for (size_t at = log.find("ignored a bad message"); at != std::string::npos;
       at = log.find("ignored a bad message", at + 1)) {
    ++lines;
  }
  EXPECT_GE(lines, 1u);
  EXPECT_LE(lines, 2u) << log;
}

/// Captures the lines the named loggers write at info level and above while it lives.
class LogCapture {
 public:
  explicit LogCapture(std::vector<std::string> names) : names_(std::move(names)) {
    sink_ = std::make_shared<spdlog::sinks::ostream_sink_mt>(out_);
    for (const std::string& name : names_) {
      auto logger = get_logger(name);
      levels_.push_back(logger->level());
      logger->set_level(spdlog::level::info);
      logger->sinks().push_back(sink_);
    }
  }
  ~LogCapture() {
    for (size_t i = 0; i < names_.size(); ++i) {
      auto logger = get_logger(names_[i]);
      logger->sinks().pop_back();
      logger->set_level(levels_[i]);
    }
  }
  /// Lines holding `text`.
  size_t lines(const std::string& text) const {
    std::istringstream in(out_.str());
    size_t n = 0;
    for (std::string line; std::getline(in, line);) n += line.find(text) != std::string::npos;
    return n;
  }
  std::string text() const { return out_.str(); }

 private:
  std::vector<std::string> names_;
  std::vector<spdlog::level::level_enum> levels_;
  std::ostringstream out_;
  std::shared_ptr<spdlog::sinks::ostream_sink_mt> sink_;
};

/// The most lines of `kind` one key may cause in `seconds`: its burst and what refills meanwhile.
size_t budget_for(PeerLog kind, std::chrono::steady_clock::duration seconds) {
  const LogBudgetSpec& s = LogBudget::spec(kind);
  return static_cast<size_t>(s.burst) +
         static_cast<size_t>(std::chrono::duration<double>(seconds).count() / s.interval_s) + 1;
}

TEST_F(BrokerTrustTest, AFloodOfEachKindOfPeerMessageIsLoggedWithinItsBudget) {
  LogCapture log({"master", "merger"});
  using SteadyClock = std::chrono::steady_clock;
  MasterOptions o = options();
  o.heartbeat.liveness = 100000;  // the test's worker sends no heartbeats
  Running master(std::move(o));
  auto alice = connect(master.broker.client_endpoint(), clients["alice"]);
  auto bob = connect(master.broker.client_endpoint(), clients["bob"]);
  const std::string id = submit_as(alice);
  auto worker = connect(master.broker.worker_endpoint(), worker_keys);
  ASSERT_TRUE(ask(worker, hello(wire::ROLE_WORKER)).as<wire::Welcome>());
  auto work = ask(worker, wire::WorkRequest{});
  ASSERT_TRUE(work.as<wire::WorkUnit>()) << work.type;
  const wire::WorkUnit unit = *work.as<wire::WorkUnit>();

  // Sends `count` copies of `frames` on `d` (a worker's connection or a client's), dropping what
  // comes back meanwhile, then waits until the master has handled all of them: it answers a
  // request of its own sent after them (a bundle or a job no one has, named uniquely).
  int syncs = 0;
  auto flood = [&syncs](net::Dealer& d, const net::Frames& frames, int count, bool is_worker) {
    const auto deadline = SteadyClock::now() + std::chrono::seconds{60};
    for (int sent = 0; sent < count && SteadyClock::now() < deadline;) {
      if (d.send(frames)) {
        ++sent;
      } else {
        d.receive(milliseconds{1});
      }
      while (d.receive(milliseconds{0})) {
      }
    }
    const std::string marker = "sync-" + std::to_string(++syncs);
    net::Frames sync;
    if (is_worker) {
      wire::BundleRequest r;
      r.set_hash(marker);
      sync = protocol::encode(r);
    } else {
      wire::StatusRequest r;
      r.set_job_id(marker);
      sync = protocol::encode(r);
    }
    // Replies past the peer's queue bound are dropped: ask until one gets through.
    bool answered = false;
    while (!answered && SteadyClock::now() < deadline) {
      d.send(sync);
      while (auto m = next(d, milliseconds{200})) {
        if (const auto* b = m->as<wire::BundleReply>()) answered |= b->hash() == marker;
        if (const auto* e = m->as<wire::Error>()) answered |= e->job_id() == marker;
      }
    }
    EXPECT_TRUE(answered);
  };

  // 5000 requests for the bundle it was just sent: each refused, a few logged.
  wire::BundleRequest bundle;
  bundle.set_hash(unit.bundle_hash());
  ASSERT_EQ(ask(worker, bundle).as<wire::BundleReply>()->error(), "");
  auto start = SteadyClock::now();
  flood(worker, protocol::encode(bundle), 5000, true);
  EXPECT_GE(log.lines("less than a minute ago"), 1u);
  EXPECT_LE(log.lines("less than a minute ago"),
            budget_for(PeerLog::kBundleRequest, SteadyClock::now() - start))
      << log.text();

  // Hellos again and again on one connection: each one a join.
  start = SteadyClock::now();
  flood(worker, protocol::encode(hello(wire::ROLE_WORKER)), 500, true);
  EXPECT_GE(log.lines(" joined with key 'w1'"), 1u);
  EXPECT_LE(log.lines(" joined with key 'w1'"),
            budget_for(PeerLog::kHello, SteadyClock::now() - start) + 1)  // + the first hello
      << log.text();

  // Results for the unit of a job cancelled meanwhile: routine, each dropped, a few logged; not
  // one counts as rejected.
  wire::CancelJob cancel;
  cancel.set_job_id(id);
  ASSERT_TRUE(ask(alice, cancel).as<wire::CancelReply>());
  const double rejected = metrics().units_rejected.value();
  const double discarded = metrics().units_discarded_job_finished.value();
  start = SteadyClock::now();
  flood(worker, protocol::encode(result_for(unit)), 500, true);
  EXPECT_EQ(metrics().units_rejected.value(), rejected);
  EXPECT_EQ(metrics().units_discarded_job_finished.value(), discarded + 500);
  EXPECT_GE(log.lines("dropped (the job is cancelled)"), 1u);
  EXPECT_LE(log.lines("dropped (the job is cancelled)"),
            budget_for(PeerLog::kResultDropped, SteadyClock::now() - start))
      << log.text();
  PrometheusText text;
  text.metrics(metrics());
  EXPECT_NE(text.text().find("rayfarm_units_discarded_total{reason=\"job_finished\"} "),
            std::string::npos);

  // A client's requests to change another key's job, and its submissions over a limit.
  const std::string other = submit_as(alice);
  wire::ChangeJob pause;
  pause.set_job_id(other);
  pause.set_paused(true);
  start = SteadyClock::now();
  flood(bob, protocol::encode(pause), 300, false);
  EXPECT_GE(log.lines("may not change job"), 1u);
  EXPECT_LE(log.lines("may not change job"),
            budget_for(PeerLog::kForbidden, SteadyClock::now() - start))
      << log.text();
  wire::SubmitJob too_many = furnace_job(8, 16, 4);
  too_many.mutable_overrides()->set_spp(1u << 30);
  start = SteadyClock::now();
  flood(bob, protocol::encode(too_many), 300, false);
  EXPECT_GE(log.lines("job refused"), 1u);
  EXPECT_LE(log.lines("job refused"),
            budget_for(PeerLog::kSubmissionRefused, SteadyClock::now() - start))
      << log.text();
}

TEST_F(BrokerTrustTest, AHiddenJobAnswersEveryRequestExactlyAsAMissingOne) {
  MasterOptions o = options();
  o.security.private_jobs = true;
  Running master(std::move(o));
  auto alice = connect(master.broker.client_endpoint(), clients["alice"]);
  auto bob = connect(master.broker.client_endpoint(), clients["bob"]);
  auto boss = connect(master.broker.client_endpoint(), clients["boss"]);
  const std::string id = submit_as(alice);
  const std::string missing = "j9999";
  ASSERT_EQ(id.size(), missing.size());
  // The requests a client can make about a job, each for a job id.
  const auto about = [](auto message, const std::string& job) {
    message.set_job_id(job);
    return protocol::encode(message);
  };
  wire::ChangeJob pause, resume, priority;
  pause.set_paused(true);
  resume.set_paused(false);
  priority.set_priority(-5);
  const std::vector<std::pair<const char*, std::function<net::Frames(const std::string&)>>>
      requests{
          {"status", [&](const std::string& j) { return about(wire::StatusRequest{}, j); }},
          {"cancel", [&](const std::string& j) { return about(wire::CancelJob{}, j); }},
          {"pause", [&](const std::string& j) { return about(pause, j); }},
          {"resume", [&](const std::string& j) { return about(resume, j); }},
          {"priority", [&](const std::string& j) { return about(priority, j); }},
          {"rm", [&](const std::string& j) { return about(wire::RemoveJob{}, j); }},
          {"retry", [&](const std::string& j) { return about(wire::RetryJob{}, j); }},
          {"fetch", [&](const std::string& j) { return about(wire::FetchImage{}, j); }},
          {"detail", [&](const std::string& j) { return about(wire::JobDetailRequest{}, j); }},
      };
  auto answer = [&](net::Dealer& d, const net::Frames& request) {
    EXPECT_TRUE(d.send(request));
    auto reply = next(d);
    EXPECT_TRUE(reply);
    return reply ? std::move(*reply) : protocol::Decoded{};
  };
  for (const auto& [what, make] : requests) {
    const protocol::Decoded hidden = answer(bob, make(id));
    const protocol::Decoded absent = answer(bob, make(missing));
    ASSERT_TRUE(hidden.as<wire::Error>()) << what << ": " << hidden.type;
    ASSERT_TRUE(absent.as<wire::Error>()) << what << ": " << absent.type;
    // The same bytes once the id asked for is swapped for the other.
    wire::Error swapped = *hidden.as<wire::Error>();
    std::string message = swapped.message();
    message.replace(message.find(id), id.size(), missing);
    swapped.set_message(message);
    swapped.set_job_id(missing);
    EXPECT_EQ(swapped.SerializeAsString(), absent.as<wire::Error>()->SerializeAsString())
        << what << ": '" << hidden.as<wire::Error>()->message() << "' and '"
        << absent.as<wire::Error>()->message() << "'";
  }

  // A worker renders one of Alice's units: Bob sees the worker, not which job it works for.
  auto worker = connect(master.broker.worker_endpoint(), worker_keys);
  ASSERT_TRUE(ask(worker, hello(wire::ROLE_WORKER)).as<wire::Welcome>());
  ASSERT_TRUE(ask(worker, wire::WorkRequest{}).as<wire::WorkUnit>());
  auto units_seen = [&](net::Dealer& d) {
    const auto list = ask(d, wire::ListWorkers{});
    EXPECT_TRUE(list.as<wire::WorkerList>()) << list.type;
    std::vector<std::string> units;
    if (!list.as<wire::WorkerList>()) return units;
    EXPECT_EQ(list.as<wire::WorkerList>()->workers_size(), 1);
    for (const auto& w : list.as<wire::WorkerList>()->workers())
      for (const auto& u : w.units()) units.push_back(u);
    return units;
  };
  const auto bobs = units_seen(bob);
  EXPECT_TRUE(bobs.empty()) << bobs.front();
  ASSERT_EQ(units_seen(alice).size(), 1u);
  EXPECT_EQ(units_seen(alice)[0].rfind(id + "/", 0), 0u) << units_seen(alice)[0];
  EXPECT_EQ(units_seen(boss).size(), 1u) << "an admin sees every job";
}

TEST_F(BrokerTrustTest, AFetchSaysWhichImageItSendsWhileTheFinalOneCannotBeWritten) {
  MasterOptions o = options();
  o.image_interval = std::chrono::hours{1};  // images at the first round and at the end only
  o.heartbeat.liveness = 100000;            // the test's worker sends no heartbeats
  Running master(std::move(o));
  auto alice = connect(master.broker.client_endpoint(), clients["alice"]);
  const std::string id = submit_as(alice);  // 8 spp: 4 tiles x 2 passes of 4
  auto worker = connect(master.broker.worker_endpoint(), worker_keys);
  ASSERT_TRUE(ask(worker, hello(wire::ROLE_WORKER)).as<wire::Welcome>());
  // Renders up to `units` leases (a lease may cover a run of a tile's passes), until the master
  // has none to give.
  auto render = [&](int units) {
    for (int i = 0; i < units; ++i) {
      ASSERT_TRUE(worker.send(protocol::encode(wire::WorkRequest{})));
      auto work = next(worker, milliseconds{2000});
      if (!work) return;
      ASSERT_TRUE(work->as<wire::WorkUnit>()) << work->type;
      worker.send(protocol::encode(result_for(*work->as<wire::WorkUnit>())));
    }
  };
  wire::StatusRequest status;
  status.set_job_id(id);
  // Waits (at most 20 s) until `done` holds for the job's status.
  auto wait_for = [&](auto done) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds{20};
    while (std::chrono::steady_clock::now() < deadline) {
      auto st = ask(alice, status);
      if (st.as<wire::JobStatus>() && done(*st.as<wire::JobStatus>())) return true;
      std::this_thread::sleep_for(milliseconds{20});
    }
    return false;
  };
  render(4);  // the first pass: its image is written
  ASSERT_TRUE(wait_for([](const wire::JobStatus& st) { return st.spp_done() == 4; }));
  const fs::path image = dir.path() / "data" / "jobs" / id / "image.exr";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds{20};
  while (!fs::exists(image) && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(milliseconds{20});
  }
  ASSERT_TRUE(fs::exists(image));
  DiskFault full(dir.path() / "data");
  render(8);  // the job's work is over; its final image cannot be written
  ASSERT_TRUE(wait_for([](const wire::JobStatus& st) { return !st.storage_error().empty(); }));
  wire::FetchImage fetch;
  fetch.set_job_id(id);
  const auto reply = ask(alice, fetch);
  const auto* data = reply.as<wire::ImageData>();
  ASSERT_TRUE(data) << reply.type;
  EXPECT_EQ(data->state(), wire::JOB_RUNNING);
  // The image sent is the first pass's, and says so; the job's figure is beside it, and why.
  EXPECT_EQ(data->spp_done(), 4u);
  EXPECT_EQ(data->job_spp_done(), 8u);
  EXPECT_NE(data->image_note().find("cannot write"), std::string::npos) << data->image_note();
  EXPECT_NE(data->image_note().find("No space left on device"), std::string::npos)
      << data->image_note();
  const fs::path copy = dir.path() / "fetched.exr";
  {
    std::ofstream out(copy, std::ios::binary);
    out << data->exr();
  }
  EXPECT_EQ(read_exr(copy).attributes.at("rayfarm:spp"), "4");
}

TEST(QueueBoundsTest, ARouterQueuesNoMoreThanItsBoundForAPeerThatDoesNotRead) {
  // Replies of 4 MiB to a peer that never reads (its own queue holds one message, so TCP pushes
  // back): past the bound, sends fail instead of queueing in the master's memory.
  zmq::context_t context;
  auto count_accepted = [&](net::QueueBounds bounds) {
    net::Router router("tcp://127.0.0.1:0", net::kDefaultMaxMessageBytes, {}, bounds);
    zmq::socket_t peer(context, zmq::socket_type::dealer);
    peer.set(zmq::sockopt::rcvhwm, 1);
    peer.set(zmq::sockopt::rcvbuf, 65536);
    peer.set(zmq::sockopt::linger, 0);
    peer.connect(router.endpoint());
    peer.send(zmq::buffer(std::string("hello")), zmq::send_flags::none);
    auto first = router.receive(milliseconds{5000});
    if (!first) return -1;
    const net::Frames big{std::string(4 << 20, 'x')};
    int accepted = 0;
    for (int i = 0; i < 40; ++i) {
      if (router.send(first->peer, big)) ++accepted;
      std::this_thread::sleep_for(milliseconds{5});
    }
    return accepted;
  };
  const int bounded = count_accepted(net::QueueBounds{2, 1});
  EXPECT_GE(bounded, 1);
  EXPECT_LE(bounded, 8) << "the send queue was not bounded";
  EXPECT_GE(count_accepted(net::QueueBounds{}), 30) << "ZeroMQ's default queue takes them";
}

TEST_F(BrokerTrustTest, AWorkerMessageIsBoundedByWhatItsUnitsCanHold) {
  Running master(options());
  auto alice = connect(master.broker.client_endpoint(), clients["alice"]);
  const std::string id = submit_as(alice);
  auto worker = connect(master.broker.worker_endpoint(), worker_keys);
  ASSERT_TRUE(ask(worker, hello(wire::ROLE_WORKER)).as<wire::Welcome>());
  auto work = ask(worker, wire::WorkRequest{});
  ASSERT_TRUE(work.as<wire::WorkUnit>()) << work.type;
  const wire::WorkUnit unit = *work.as<wire::WorkUnit>();
  const auto dropped = [] {
    const auto v = metrics().refusals.values();
    const auto it = v.find("worker_message_size");
    return it == v.end() ? 0.0 : it->second;
  };
  // The unit's result (a 16 x 16 tile) takes tens of kilobytes; the connection may send up to
  // WorkerMessageBounds::kSmallMessageBytes. A result padded past it, from the holder itself or
  // from a connection that holds nothing, is dropped before it is decoded.
  wire::UnitResult padded = result_for(unit);
  padded.mutable_sum()->append(WorkerMessageBounds::kSmallMessageBytes, '\x01');
  auto idle = connect(master.broker.worker_endpoint(), worker_keys);
  ASSERT_TRUE(ask(idle, hello(wire::ROLE_WORKER)).as<wire::Welcome>());
  idle.send(protocol::encode(padded));
  worker.send(protocol::encode(padded));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds{5};
  while (dropped() < 2 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(milliseconds{10});
  }
  EXPECT_EQ(dropped(), 2.0);
  wire::StatusRequest status;
  status.set_job_id(id);
  EXPECT_EQ(ask(alice, status).as<wire::JobStatus>()->units_done(), 0u);
  // Within the bound, the holder's result is read and merged as ever.
  worker.send(protocol::encode(result_for(unit)));
  uint64_t done = 0;
  while (done == 0 && std::chrono::steady_clock::now() < deadline + std::chrono::seconds{5}) {
    done = ask(alice, status).as<wire::JobStatus>()->units_done();
  }
  EXPECT_EQ(done, 1u);
  EXPECT_EQ(dropped(), 2.0);
}

/// A ChangeWorker of `control` for worker `worker` (its id or its name).
wire::ChangeWorker worker_control(const std::string& worker, wire::ChangeWorker::Control control) {
  wire::ChangeWorker c;
  c.set_worker(worker);
  c.set_control(control);
  return c;
}

/// The code of the Error `reply` is; CODE_UNSPECIFIED (a failure) when it is no Error.
wire::Error::Code error_code(const protocol::Decoded& reply) {
  const auto* e = reply.as<wire::Error>();
  EXPECT_TRUE(e) << "not an error: " << reply.type;
  return e ? e->code() : wire::Error::CODE_UNSPECIFIED;
}

TEST_F(BrokerTrustTest, AWorkerIsDrainedDisabledAndEnabledByItsOwnKeyOrAnAdminOnly) {
  clients.emplace("w1", net::generate_key_pair());  // the client key of the worker key's name
  MasterOptions o = options();
  o.heartbeat.liveness = 100000;  // the test's workers send no heartbeats
  Running master(std::move(o));
  auto alice = connect(master.broker.client_endpoint(), clients["alice"]);
  auto owner = connect(master.broker.client_endpoint(), clients["w1"]);
  auto boss = connect(master.broker.client_endpoint(), clients["boss"]);
  const std::string id = submit_as(alice);  // 4 tiles x 2 passes
  auto worker = connect(master.broker.worker_endpoint(), worker_keys);
  ASSERT_TRUE(ask(worker, hello(wire::ROLE_WORKER)).as<wire::Welcome>());
  const auto first = ask(worker, wire::WorkRequest{});
  ASSERT_TRUE(first.as<wire::WorkUnit>()) << first.type;
  const auto list = ask(alice, wire::ListWorkers{});
  ASSERT_TRUE(list.as<wire::WorkerList>());
  ASSERT_EQ(list.as<wire::WorkerList>()->workers_size(), 1);
  const wire::WorkerInfo listed = list.as<wire::WorkerList>()->workers(0);
  EXPECT_EQ(listed.control(), "enabled");
  const std::string wid = listed.id();

  // Alice's key is neither the worker's nor an admin's: refused, whatever she asks.
  for (auto c :
       {wire::ChangeWorker::DRAIN, wire::ChangeWorker::DISABLE, wire::ChangeWorker::ENABLE}) {
    EXPECT_EQ(error_code(ask(alice, worker_control(wid, c))), wire::Error::FORBIDDEN);
  }
  EXPECT_EQ(error_code(ask(owner, worker_control("nobody", wire::ChangeWorker::DRAIN))),
            wire::Error::NOT_FOUND);
  EXPECT_EQ(error_code(ask(owner, worker_control(wid, wire::ChangeWorker::CONTROL_UNSPECIFIED))),
            wire::Error::BAD_REQUEST);

  // Drained by its own key, named by its name: it keeps its unit and gets no new one.
  const auto drained = ask(owner, worker_control(listed.name(), wire::ChangeWorker::DRAIN));
  ASSERT_TRUE(drained.as<wire::ChangeWorkerReply>()) << drained.type;
  EXPECT_EQ(drained.as<wire::ChangeWorkerReply>()->worker().control(), "draining");
  EXPECT_EQ(drained.as<wire::ChangeWorkerReply>()->worker().units_size(), 1);
  EXPECT_EQ(drained.as<wire::ChangeWorkerReply>()->units_requeued(), 0u);
  ASSERT_TRUE(worker.send(protocol::encode(wire::WorkRequest{})));
  EXPECT_FALSE(next(worker, std::chrono::milliseconds{400})) << "a draining worker got work";

  // Disabled by an admin: its unit goes back to the queue, and another connection of the same
  // key gets exactly that unit.
  const auto disabled = ask(boss, worker_control(wid, wire::ChangeWorker::DISABLE));
  ASSERT_TRUE(disabled.as<wire::ChangeWorkerReply>()) << disabled.type;
  EXPECT_EQ(disabled.as<wire::ChangeWorkerReply>()->worker().control(), "disabled");
  EXPECT_EQ(disabled.as<wire::ChangeWorkerReply>()->units_requeued(), 1u);
  EXPECT_EQ(disabled.as<wire::ChangeWorkerReply>()->worker().units_size(), 0);
  {
    auto other = connect(master.broker.worker_endpoint(), worker_keys);
    wire::Hello h = hello(wire::ROLE_WORKER);
    h.set_name("other");
    ASSERT_TRUE(ask(other, h).as<wire::Welcome>());
    const auto again = ask(other, wire::WorkRequest{});
    ASSERT_TRUE(again.as<wire::WorkUnit>()) << again.type;
    EXPECT_EQ(again.as<wire::WorkUnit>()->unit_id(), first.as<wire::WorkUnit>()->unit_id());
    ASSERT_TRUE(other.send(protocol::encode(wire::Goodbye{})));
  }
  // A worker that says hello again stays disabled: under the same name and key, and on the same
  // connection under another name.
  ASSERT_TRUE(ask(worker, hello(wire::ROLE_WORKER)).as<wire::Welcome>());
  ASSERT_TRUE(worker.send(protocol::encode(wire::WorkRequest{})));
  EXPECT_FALSE(next(worker, std::chrono::milliseconds{400})) << "a disabled worker got work";
  {
    wire::Hello renamed = hello(wire::ROLE_WORKER);
    renamed.set_name("renamed");
    ASSERT_TRUE(ask(worker, renamed).as<wire::Welcome>());
    ASSERT_TRUE(worker.send(protocol::encode(wire::WorkRequest{})));
    EXPECT_FALSE(next(worker, std::chrono::milliseconds{400})) << "a renamed worker got work";
    ASSERT_TRUE(ask(worker, hello(wire::ROLE_WORKER)).as<wire::Welcome>());  // "test" again
    ASSERT_TRUE(worker.send(protocol::encode(wire::WorkRequest{})));
  }

  // Enabled by its own key: its waiting request is answered at once.
  const auto enabled = ask(owner, worker_control(wid, wire::ChangeWorker::ENABLE));
  ASSERT_TRUE(enabled.as<wire::ChangeWorkerReply>()) << enabled.type;
  EXPECT_EQ(enabled.as<wire::ChangeWorkerReply>()->worker().control(), "enabled");
  const auto unit = next(worker);
  ASSERT_TRUE(unit && unit->as<wire::WorkUnit>()) << (unit ? unit->type : "nothing");
  EXPECT_EQ(unit->as<wire::WorkUnit>()->job_id(), id);

  // The job's log says where its unit went and why.
  wire::JobDetailRequest request;
  request.set_job_id(id);
  const auto detail = ask(alice, request);
  ASSERT_TRUE(detail.as<wire::JobDetail>()) << detail.type;
  bool said = false;
  for (const auto& line : detail.as<wire::JobDetail>()->log()) {
    said = said || line.text().find("back in the queue: its worker was disabled by key 'boss'") !=
                       std::string::npos;
  }
  EXPECT_TRUE(said) << detail.as<wire::JobDetail>()->DebugString();
}

TEST_F(BrokerTrustTest, AJobsDetailNamesItsUnitsWorkersAndTheWorkersWordsForAFailure) {
  MasterOptions o = options();
  o.heartbeat.liveness = 100000;
  Running master(std::move(o));
  auto alice = connect(master.broker.client_endpoint(), clients["alice"]);
  const std::string id = submit_as(alice);
  auto worker = connect(master.broker.worker_endpoint(), worker_keys);
  ASSERT_TRUE(ask(worker, hello(wire::ROLE_WORKER)).as<wire::Welcome>());
  const auto leased = ask(worker, wire::WorkRequest{});
  ASSERT_TRUE(leased.as<wire::WorkUnit>()) << leased.type;
  const uint64_t unit = leased.as<wire::WorkUnit>()->unit_id();
  wire::JobDetailRequest request;
  request.set_job_id(id);
  auto detail = [&] {
    const auto reply = ask(alice, request);
    EXPECT_TRUE(reply.as<wire::JobDetail>()) << reply.type;
    return reply.as<wire::JobDetail>() ? *reply.as<wire::JobDetail>() : wire::JobDetail{};
  };
  // Leased: rendering, on the worker, handed out once.
  wire::JobDetail d = detail();
  EXPECT_EQ(d.status().job_id(), id);
  EXPECT_GT(d.status().submitted_unix_ms(), 0);
  EXPECT_GE(d.status().started_unix_ms(), d.status().submitted_unix_ms());
  EXPECT_EQ(d.status().finished_unix_ms(), 0);
  ASSERT_GE(d.units_size(), 1);
  EXPECT_EQ(d.units(0).unit_id(), unit);
  EXPECT_EQ(d.units(0).state(), "rendering");
  ASSERT_EQ(d.units(0).workers_size(), 1);
  EXPECT_NE(d.units(0).workers(0).find("test"), std::string::npos) << d.units(0).workers(0);
  EXPECT_EQ(d.units(0).leases(), 1u);
  EXPECT_EQ(d.units_queued(), 7u);

  // It fails there: queued again, with the worker's words, in the units and in the log.
  wire::UnitFailed failed;
  failed.set_job_id(id);
  failed.set_unit_id(unit);
  failed.set_reason("the scene's texture is missing on this machine");
  ASSERT_TRUE(worker.send(protocol::encode(failed)));
  ASSERT_TRUE(worker.send(protocol::encode(wire::WorkRequest{})));
  const auto again = next(worker);
  ASSERT_TRUE(again && again->as<wire::WorkUnit>());
  d = detail();
  const wire::UnitInfo* info = nullptr;
  for (const auto& u : d.units()) {
    if (u.unit_id() == unit) info = &u;
  }
  ASSERT_TRUE(info) << d.DebugString();
  EXPECT_EQ(info->error(), "the scene's texture is missing on this machine");
  EXPECT_EQ(info->leases(), again->as<wire::WorkUnit>()->unit_id() == unit ? 2u : 1u);
  EXPECT_EQ(d.units_failed(), 1u);
  bool logged = false;
  for (const auto& line : d.log()) {
    logged = logged || (line.level() == "warning" &&
                        line.text().find("the scene's texture is missing") != std::string::npos &&
                        line.text().find("unit " + std::to_string(unit)) != std::string::npos);
  }
  EXPECT_TRUE(logged) << d.DebugString();
  ASSERT_EQ(d.workers_size(), 1);
  EXPECT_EQ(d.workers(0).failures(), 1u);
}

}  // namespace
}  // namespace rayfarm::master

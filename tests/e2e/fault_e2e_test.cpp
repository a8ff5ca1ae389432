// Faults injected into a real farm on loopback (a master, workers and the rayfarm CLI, all with
// --insecure so that these tests depend on nothing but the durability code): the master stopped
// with SIGTERM and killed with SIGKILL mid-job resumes from its checkpoint, also when the newest
// checkpoint is corrupt; a frozen worker (SIGSTOP) has its unit leased again as a straggler and its
// late result dropped; a worker returning corrupt results is blocked from the job. Every job ends
// with an EXR bit-identical to `rayfarm render`. Every wait is bounded; every process is killed by
// PID when its test ends, passed or failed. (A worker killed with SIGKILL: farm_e2e_test.cpp.)
#include <gtest/gtest.h>

#include <signal.h>

#include "tests/e2e/farm_fixture.h"

namespace rayfarm::test {
namespace {

class FaultTest : public FarmFixture {
 protected:
  std::vector<std::string> client_auth() const override { return {"--insecure"}; }
  net::Curve client_curve() const override { return {}; }

  /// Starts the master (again: same ports, same data dir) logging to `log`.
  void start_master(const std::string& log, const std::vector<std::string>& extra = {}) {
    std::vector<std::string> options{"--insecure", "--image-interval-ms", "500"};
    options.insert(options.end(), extra.begin(), extra.end());
    run_master(log, options);
  }

  Process& start_worker(const std::string& name, const std::vector<std::string>& extra = {}) {
    std::vector<std::string> options{"--insecure", "--threads", "1", "--reconnect-max-ms", "500"};
    options.insert(options.end(), extra.begin(), extra.end());
    return run_worker(name, options);
  }
};

/// The number after `marker` in the last line of `log` holding it ("... at 12/64 units").
long number_after(const std::string& log, const std::string& marker) {
  const size_t at = log.rfind(marker);
  if (at == std::string::npos) return -1;
  return std::strtol(log.c_str() + at + marker.size(), nullptr, 10);
}

TEST_F(FaultTest, TheMasterStoppedOrKilledMidJobResumesFromItsCheckpoint) {
  const std::vector<std::string> master_options{"--checkpoint-interval-ms", "200"};
  start_master("master-1.log", master_options);
  Process& w = start_worker("w");
  // A target error, so that the planner's decisions must survive the restarts too: tiles stop
  // after about 18 of their 32 passes; the same tiles and passes locally give the same decisions.
  const fs::path scene = small_scene("cornell-box", 32);
  const std::vector<std::string> settings{"--spp",          "2048",   "--seed",       "4",
                                          "--tile",         "16",     "--pass-spp",   "64",
                                          "--target-error", "0.0025", "--min-passes", "2"};
  const std::string job = submit(scene, settings);  // 4 tiles x 32 passes = 128 units at most
  ASSERT_EQ(job, "j0001");

  // SIGTERM: the master checkpoints the running job and exits 0.
  ASSERT_TRUE(wait_until([&] { return status(job).units_done() >= 12; }, milliseconds{30000}));
  w.signal(SIGSTOP);  // whatever the machine's load, the job is still running when the master stops
  master().signal(SIGTERM);
  ASSERT_EQ(master().wait(milliseconds{10000}), std::optional<int>(0));
  EXPECT_NE(master().log().find("1 running job checkpointed"), std::string::npos);

  const auto restarted = fs::file_time_type::clock::now();
  start_master("master-2.log", master_options);
  w.signal(SIGCONT);
  const long resumed_at = number_after(master().log(), "job j0001 resumed from checkpoint at ");
  EXPECT_GE(resumed_at, 12) << master().log();

  // SIGKILL once this master has checkpointed progress of its own: the newest checkpoint is
  // corrupted on disk, and the master falls back to the one before (this master's or the last
  // of the first master), which holds at least what the second master resumed from.
  ASSERT_TRUE(wait_until([&] { return status(job).units_done() >= uint64_t(resumed_at) + 12; },
                         milliseconds{30000}));
  w.signal(SIGSTOP);  // the job cannot end before the kill
  const fs::path a = job_dir(job) / "checkpoint-0.bin", b = job_dir(job) / "checkpoint-1.bin";
  const auto written_since_restart = [&](const fs::path& file) {
    std::error_code error;
    const auto time = fs::last_write_time(file, error);
    return !error && time > restarted;
  };
  ASSERT_TRUE(wait_until([&] { return written_since_restart(a) || written_since_restart(b); },
                         milliseconds{30000}));
  master().signal(SIGKILL);
  ASSERT_TRUE(master().wait(milliseconds{5000}));
  ASSERT_TRUE(fs::exists(a) && fs::exists(b));
  const fs::path newest = fs::last_write_time(a) > fs::last_write_time(b) ? a : b;
  const fs::path older = newest == a ? b : a;
  {
    std::fstream f(newest, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(fs::file_size(newest) / 2));
    f.put('\x42');
    f.put('\x24');
  }
  start_master("master-3.log", master_options);
  w.signal(SIGCONT);
  const std::string log3 = master().log();
  EXPECT_TRUE(has_line(
      log3, "job j0001: cannot use checkpoint " + newest.string(),
      "checksum mismatch (SHA-256): the file is corrupt; falling back to " + older.string()))
      << log3;
  EXPECT_GE(number_after(log3, "job j0001 resumed from checkpoint at "), resumed_at) << log3;

  wait_for_state(job, wire::JOB_DONE);
  const wire::JobStatus done = status(job);
  EXPECT_LT(done.units_done(), 128u) << "the target error stopped tiles early";
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
  // Nothing was merged twice: the merger never saw a duplicate (one worker, no stragglers).
  for (const char* log : {"master-1.log", "master-2.log", "master-3.log"}) {
    EXPECT_EQ(count_of(read_file(dir() / log), "duplicate result"), 0u) << log;
  }
  EXPECT_TRUE(wait_until([&] { return !fs::exists(a) && !fs::exists(b); }, milliseconds{10000}))
      << "a finished job keeps no checkpoint";
}

TEST_F(FaultTest, AFrozenWorkersUnitIsLeasedAgainAndItsLateResultDropped) {
  // A long liveness window, so that the straggler rule (not the loss of heartbeats) replaces it.
  // (50 s: the steady worker must first render every other unit, slowly on a loaded machine.)
  start_master("master.log", {"--heartbeat-ms", "500", "--liveness", "100", "--straggler-factor",
                              "3", "--straggler-min-ms", "300"});
  Process& frozen = start_worker("frozen", {"--heartbeat-ms", "500", "--liveness", "100"});
  start_worker("steady", {"--heartbeat-ms", "500", "--liveness", "100"});
  const fs::path scene = small_scene("cornell-box", 64);
  const std::vector<std::string> settings{"--spp", "256", "--seed", "8"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "16", "--pass-spp", "32"});  // 128 units
  const std::string job = submit(scene, job_settings);
  ASSERT_TRUE(wait_until([&] { return status(job).units_done() >= 8; }, milliseconds{30000}));

  // Freeze it while it holds a lease: both workers hold one.
  bool stopped = false;
  for (int attempt = 0; attempt < 100 && !stopped; ++attempt) {
    frozen.signal(SIGSTOP);
    std::this_thread::sleep_for(milliseconds{20});
    if (status(job).workers_busy() == 2) {
      stopped = true;
    } else {
      frozen.signal(SIGCONT);
      std::this_thread::sleep_for(milliseconds{20});
    }
  }
  ASSERT_TRUE(stopped) << "the frozen worker never held a lease";
  wait_for_state(job, wire::JOB_DONE, seconds{120});
  std::string log = master().log();
  EXPECT_TRUE(
      has_line(log, "is a straggler: leased to worker frozen (", "also leased to worker steady ("))
      << "no straggler line";
  EXPECT_FALSE(has_line(log, "worker frozen (", ") lost"))
      << "replaced before its heartbeats ran out";
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));

  // Thawed, it sends its result late: dropped as a duplicate.
  frozen.signal(SIGCONT);
  EXPECT_TRUE(wait_until(
      [&] { return has_line(master().log(), "duplicate result from worker frozen (", "dropped"); },
      milliseconds{10000}))
      << master().log();
}

TEST_F(FaultTest, AWorkerReturningCorruptResultsIsBlockedAndTheImageStaysRight) {
  start_master("master.log", {"--liveness", "40", "--max-worker-failures", "3"});
  const fs::path scene = small_scene("cornell-box", 32);
  const std::vector<std::string> settings{"--spp", "64", "--seed", "5"};
  std::vector<std::string> job_settings = settings;
  job_settings.insert(job_settings.end(), {"--tile", "16", "--pass-spp", "16"});  // 16 units
  const std::string job = submit(scene, job_settings);

  // A worker of our own that answers units with results of the wrong size, then fails one.
  RawPeer fake(worker_endpoint());
  wire::Hello hello;
  hello.set_role(wire::ROLE_WORKER);
  hello.set_name("corrupt");
  fake.send(protocol::encode(hello));
  fake.expect<wire::Welcome>();
  for (int i = 0; i < 3; ++i) {
    fake.send(protocol::encode(wire::WorkRequest{}));
    const auto unit = fake.expect<wire::WorkUnit>();
    if (i < 2) {
      const TileRect rect = protocol::rect_from_wire(unit.tile());
      TileResult bad(rect, {unit.sample_begin(), unit.sample_end()});
      bad.sum.resize(bad.sum.size() / 2);
      fake.send(
          protocol::encode(protocol::result_to_wire(unit.job_id(), unit.unit_id(), bad, 0.0)));
    } else {
      wire::UnitFailed failed;
      failed.set_job_id(unit.job_id());
      failed.set_unit_id(unit.unit_id());
      failed.set_reason("injected failure");
      fake.send(protocol::encode(failed));
    }
  }
  ASSERT_TRUE(wait_until(
      [&] {
        return has_line(master().log(), "job j0001: worker corrupt (",
                        "blocked from the job after 3 failures");
      },
      milliseconds{5000}))
      << master().log();
  // Blocked: it asks, and gets nothing although the job has units left.
  fake.send(protocol::encode(wire::WorkRequest{}));
  EXPECT_FALSE(fake.receive(milliseconds{1000})) << "a blocked worker got a unit";
  EXPECT_NE(status(job).state(), wire::JOB_FAILED);

  start_worker("good");
  wait_for_state(job, wire::JOB_DONE);
  const std::string log = master().log();
  EXPECT_EQ(count_of(log, "result from worker corrupt ("), 2u) << log;
  EXPECT_TRUE(has_line(log, "failed on worker corrupt (", "injected failure"));
  EXPECT_TRUE(bit_identical(fetch(job), local_render(scene, settings)));
}

}  // namespace
}  // namespace rayfarm::test

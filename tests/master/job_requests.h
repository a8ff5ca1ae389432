#pragma once
// Requests and results for tests of the master's jobs: a submission of the bundled furnace, a
// result of the right shape for a unit, and a wait for a job's time limit.
#include <chrono>
#include <filesystem>
#include <string>
#include <thread>

#include "common/bundle/bundle.h"
#include "common/image/film.h"
#include "common/image/fixed.h"
#include "common/protocol/convert.h"
#include "master/job_manager.h"
#include "proto/rayfarm.pb.h"

namespace rayfarm::master::test_jobs {

/// A submit request for the bundled furnace (32x32) with these overrides.
inline wire::SubmitJob furnace_job(uint32_t spp, uint32_t tile, uint32_t pass_spp) {
  const PackedScene packed =
      pack_scene(std::filesystem::path(RAYFARM_SOURCE_DIR) / "scenes" / "furnace" / "scene.json");
  wire::SubmitJob request;
  protocol::bundle_to_wire(packed.bundle, request.mutable_bundle());
  request.set_scene_path(packed.scene_path);
  request.set_name("furnace");
  request.mutable_overrides()->set_spp(spp);
  request.mutable_overrides()->set_tile_size(tile);
  request.mutable_overrides()->set_pass_spp(pass_spp);
  return request;
}

/// A result of the right shape for `unit`, every sample worth `value`.
inline wire::UnitResult result_for(const wire::WorkUnit& unit, double value = 0.5) {
  const TileRect rect = protocol::rect_from_wire(unit.tile());
  TileResult r(rect, {unit.sample_begin(), unit.sample_end()});
  const double n = unit.sample_end() - unit.sample_begin();
  for (auto& s : r.sum) s = to_fixed(value * n);
  for (auto& s : r.sum_sq) s = to_fixed(value * value * n);
  return protocol::result_to_wire(unit.job_id(), unit.unit_id(), r, 0.01);
}

/// Ticks `jobs` until job `id` is no longer running, for at most 30 s (a time limit to pass).
inline void tick_while_running(JobManager& jobs, const std::string& id) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (jobs.status(id, 1)->state() == wire::JOB_RUNNING &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    jobs.tick();
  }
}

}  // namespace rayfarm::master::test_jobs

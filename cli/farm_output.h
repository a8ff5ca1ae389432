#pragma once
// How the farm commands show what the master says: status lines and tables for people, one JSON
// object per line for scripts (docs/cli.md lists the keys).
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "proto/rayfarm.pb.h"

namespace rayfarm::cli {

/// "12.5 s", "3m07s" or "2h05m"; "?" when negative.
std::string format_duration(double seconds);
/// Unix milliseconds as local time, "2026-12-07 16:45:12"; "-" for 0 (not yet).
std::string format_time(int64_t unix_ms);
/// Whether a job in `state` has ended (done, failed, cancelled, or unknown to the master).
bool finished(wire::JobState state);
/// The job's state as people read it: "paused" for a paused queued or running job.
std::string state_label(const wire::JobStatus& st);

/// A job's status as one JSON object.
nlohmann::json status_json(const wire::JobStatus& st);
/// A worker as one JSON object.
nlohmann::json worker_json(const wire::WorkerInfo& w);
/// Prints `j` on one line of standard output, flushed.
void print_json(const nlohmann::json& j);

/// The one-line progress of a job, as watch shows it.
std::string progress_line(const wire::JobStatus& st);
/// A job's status, several lines, as status shows it.
void print_status(const wire::JobStatus& st);
/// The jobs as a table, as list shows them.
void print_table(const wire::JobList& list);
/// A job's units, its workers' shares and its log, as `status JOB --detail` shows them after
/// its status (detail_output.cpp); and all of it as one JSON object.
void print_detail(const wire::JobDetail& detail);
nlohmann::json detail_json(const wire::JobDetail& detail);
/// A worker's state as people read it: disabled, draining, drained (draining, holding no
/// units), busy or idle.
std::string worker_state(const wire::WorkerInfo& w);

}  // namespace rayfarm::cli

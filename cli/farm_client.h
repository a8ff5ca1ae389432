#pragma once
// What commands outside farm_commands.cpp (report) borrow from the farm's client commands: the
// same --master / --timeout options, connection, error messages and exit codes as fetch and
// status. Implemented in farm_commands.cpp, beside the client it wraps.
#include <functional>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "proto/rayfarm.pb.h"

namespace rayfarm::cli {

/// A job as the master has it now: its status and, once a unit has been merged, its image (with
/// error.csv and error.png when the master wrote them).
struct JobSnapshot {
  wire::JobStatus status;
  std::optional<wire::ImageData> image;
  std::string no_image_reason;  ///< the master's answer when there is no image
};

/// Fetches a job's snapshot; throws as the farm commands' client does (see run_farm_command).
using JobFetcher = std::function<JobSnapshot(const std::string& job_id)>;

/// Adds --master (default $RAYFARM_MASTER or tcp://localhost:5556) and --timeout to `cmd`;
/// the returned fetcher uses their values, so call it only after parsing.
JobFetcher add_job_fetch_options(CLI::App* cmd);

/// Runs `body` as the farm commands run theirs: an error is printed as "rayfarm COMMAND: error:
/// cause"; returns body's exit code, 1 on an error, 3 when the master is unreachable.
int run_farm_command(const char* command, const std::function<int()>& body);

}  // namespace rayfarm::cli

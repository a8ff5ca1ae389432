#pragma once
// The farm's client commands, one function each, registered together by add_farm_commands()
// (commands.h). Each adds one subcommand to `app` whose callback sets `exit_code`.
#include <cmath>

#include <CLI/CLI.hpp>

#include "proto/rayfarm.pb.h"

namespace rayfarm::cli {

/// A job's status as people are shown it: an error figure that is not finite (a job cancelled
/// before a pixel had two samples) is unknown, shown as no figure rather than "inf".
inline wire::JobStatus for_people(wire::JobStatus st) {
  if (!std::isfinite(st.est_rel_mse())) st.set_est_rel_mse(-1);
  if (!std::isfinite(st.ref_rel_mse())) st.set_ref_rel_mse(-1);
  return st;
}

// submit_watch_commands.cpp
void add_submit(CLI::App& app, int& exit_code);
void add_watch(CLI::App& app, int& exit_code);
// job_commands.cpp
void add_status(CLI::App& app, int& exit_code);
void add_list(CLI::App& app, int& exit_code);
void add_cancel(CLI::App& app, int& exit_code);
void add_pause(CLI::App& app, int& exit_code);  // pause and resume
void add_set_priority(CLI::App& app, int& exit_code);
void add_remove(CLI::App& app, int& exit_code);
void add_retry(CLI::App& app, int& exit_code);
// workers_fetch_commands.cpp
void add_workers(CLI::App& app, int& exit_code);
void add_fetch(CLI::App& app, int& exit_code);
void add_token(CLI::App& app, int& exit_code);  // the HTTP endpoint's bearer token
// worker_commands.cpp
void add_worker_controls(CLI::App& app, int& exit_code);  // drain, disable, enable

}  // namespace rayfarm::cli

#pragma once
// The farm's client commands, one function each, registered together by add_farm_commands()
// (commands.h). Each adds one subcommand to `app` whose callback sets `exit_code`.
#include <CLI/CLI.hpp>

namespace rayfarm::cli {

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

}  // namespace rayfarm::cli

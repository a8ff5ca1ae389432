#pragma once
// The subcommands of `rayfarm`. Each add_*_command registers one or more subcommands on `app`;
// their callbacks set `exit_code` (0 on success) and print errors themselves, naming the cause.
#include <CLI/CLI.hpp>

namespace rayfarm::cli {

/// `rayfarm render SCENE -o OUT.exr ...`: renders on this machine.
void add_render_command(CLI::App& app, int& exit_code);
/// `rayfarm compare A.exr B.exr`: error metrics; exit 0 only when bit-identical.
void add_compare_command(CLI::App& app, int& exit_code);
/// The farm's client commands (submit, status, list, watch, cancel, fetch), each with --master
/// (default $RAYFARM_MASTER or tcp://localhost:5556) and --timeout. Exit codes: 0 success, 1 error,
/// 2 the job failed or was cancelled (submit --wait, watch), 3 master unreachable, 130 Ctrl-C.
void add_farm_commands(CLI::App& app, int& exit_code);

}  // namespace rayfarm::cli

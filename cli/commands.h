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
/// (default $RAYFARM_MASTER or tcp://localhost:5556), --timeout, --key and --master-key (or
/// --insecure). Exit codes: 0 success, 1 error, 2 usage error (main.cpp), 3 master unreachable,
/// 4 the master refused this client's key, 5 the job failed or was cancelled (submit --wait,
/// watch), 130 Ctrl-C.
void add_farm_commands(CLI::App& app, int& exit_code);
/// `rayfarm keygen [-o DIR] [--name NAME]`: writes DIR/NAME.key and DIR/NAME.key_secret.
void add_keygen_command(CLI::App& app, int& exit_code);
/// `rayfarm report TARGET [-o PLOT.png]`: a render's error against time (an error.csv here, or a
/// job on the master): table, summary, plot. Exit codes as the farm commands'.
void add_report_command(CLI::App& app, int& exit_code);

}  // namespace rayfarm::cli

// The farm's client commands, registered in the order `rayfarm --help` lists them. The client is
// in farm_client.*, the printing in farm_output.*, and the commands in submit_watch_commands.cpp,
// job_commands.cpp, workers_fetch_commands.cpp (with token) and worker_commands.cpp.
#include "cli/farm_commands.h"
#include "cli/commands.h"

namespace rayfarm::cli {

void add_farm_commands(CLI::App& app, int& exit_code) {
  add_submit(app, exit_code);
  add_status(app, exit_code);
  add_list(app, exit_code);
  add_watch(app, exit_code);
  add_cancel(app, exit_code);
  add_pause(app, exit_code);
  add_set_priority(app, exit_code);
  add_fetch(app, exit_code);
  add_workers(app, exit_code);
  add_worker_controls(app, exit_code);
  add_remove(app, exit_code);
  add_retry(app, exit_code);
  add_token(app, exit_code);
}

}  // namespace rayfarm::cli

// drain, disable and enable: take a worker out of the farm, or put it back. The master remembers
// it while it runs, also when the worker reconnects under the same name and key.
#include <iostream>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "cli/farm_client.h"
#include "cli/farm_commands.h"
#include "cli/farm_output.h"

namespace rayfarm::cli {
using protocol::encode;

namespace {

void add_control(CLI::App& app, int& exit_code, const char* name, const std::string& help,
                 wire::ChangeWorker::Control control) {
  auto args = std::make_shared<ClientArgs>();
  auto worker = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(name, help);
  cmd->add_option("worker", *worker,
                  "The worker's id (`rayfarm workers` shows it), or its name when no other "
                  "connected worker has it")
      ->required();
  add_client_options(cmd, *args);
  cmd->add_flag("--json", *json, "The worker afterwards as one JSON object");
  cmd->callback([args, worker, json, name, control, &exit_code] {
    exit_code = guarded(name, [&] {
      FarmClient client(*args);
      wire::ChangeWorker request;
      request.set_worker(*worker);
      request.set_control(control);
      const auto reply = client.call<wire::ChangeWorkerReply>(encode(std::move(request)));
      const wire::WorkerInfo& w = reply.worker();
      if (*json) {
        nlohmann::json out = worker_json(w);
        out["units_requeued"] = reply.units_requeued();
        print_json(out);
        return 0;
      }
      std::cout << fmt::format("worker {} ({}) {}", w.name(), w.id(), worker_state(w));
      if (reply.units_requeued() > 0) {
        std::cout << fmt::format(": {} unit{} back in the queue", reply.units_requeued(),
                                 reply.units_requeued() == 1 ? "" : "s");
      } else if (worker_state(w) == "draining") {
        std::cout << fmt::format(": it finishes the {} unit{} it holds", w.units_size(),
                                 w.units_size() == 1 ? "" : "s");
      }
      std::cout << "\n";
      return 0;
    });
  });
}

}  // namespace

void add_worker_controls(CLI::App& app, int& exit_code) {
  add_control(app, exit_code, "drain",
              "Let a worker finish the units it holds and give it no new ones (until `rayfarm "
              "enable`): the worker's own key or an admin key",
              wire::ChangeWorker::DRAIN);
  add_control(app, exit_code, "disable",
              "Give a worker no units, and put those it holds back in the queue at once (until "
              "`rayfarm enable`): the worker's own key or an admin key",
              wire::ChangeWorker::DISABLE);
  add_control(app, exit_code, "enable", "Give a drained or disabled worker units again",
              wire::ChangeWorker::ENABLE);
}

}  // namespace rayfarm::cli

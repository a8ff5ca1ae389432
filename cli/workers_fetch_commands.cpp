// workers, fetch and token: the farm's workers, a job's image brought home, and the token that
// lets this key act on the master's dashboard.
#include <iostream>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "cli/farm_client.h"
#include "cli/farm_commands.h"
#include "cli/farm_output.h"
#include "cli/output_path.h"
#include "common/protocol/convert.h"
#include "common/util/text.h"

namespace rayfarm::cli {
namespace fs = std::filesystem;
using protocol::encode;

void add_workers(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand("workers", "List the workers connected to the master");
  add_client_options(cmd, *args);
  cmd->add_flag("--json", *json, "One JSON object per worker, one a line");
  cmd->callback([args, json, &exit_code] {
    exit_code = guarded("workers", [&] {
      FarmClient client(*args);
      const auto list = client.call<wire::WorkerList>(encode(wire::ListWorkers{}));
      if (*json) {
        for (const auto& w : list.workers()) print_json(worker_json(w));
        return 0;
      }
      if (list.workers().empty()) {
        std::cout << "no workers connected\n";
        return 0;
      }
      std::cout << fmt::format("{:<20} {:<10} {:<16} {:<8} {:>7} {:<16} {:>6} {:>16} {:>9}\n",
                               "NAME", "ID", "KEY", "STATE", "THREADS", "UNIT", "DONE", "RATE",
                               "SEEN");
      for (const auto& w : list.workers()) {
        std::string units = w.units().empty() ? "-" : w.units(0);
        if (w.units_size() > 1) units += fmt::format(" +{}", w.units_size() - 1);
        std::cout << fmt::format(
            "{:<20} {:<10} {:<16} {:<8} {:>7} {:<16} {:>6} {:>16} {:>9}\n", w.name().substr(0, 20),
            w.id(), w.key_name().empty() ? "-" : w.key_name().substr(0, 16), worker_state(w),
            w.threads(), units, w.units_done(), human_rate(w.samples_per_second()),
            format_duration(w.last_seen_seconds()) + " ago");
      }
      return 0;
    });
  });
}

void add_token(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "token",
      "Print this key's bearer token for the master's HTTP endpoint (the dashboard's actions and "
      "its JSON API: 'Authorization: Bearer TOKEN')");
  add_client_options(cmd, *args);
  cmd->add_flag("--json", *json, "{\"token\": ..., \"key\": ...} as one JSON line");
  cmd->callback([args, json, &exit_code] {
    exit_code = guarded("token", [&] {
      FarmClient client(*args);
      const auto reply = client.call<wire::TokenReply>(encode(wire::TokenRequest{}));
      if (*json) {
        print_json(nlohmann::json{{"token", reply.token()}, {"key", reply.key_name()}});
      } else {
        std::cout << reply.token() << "\n";
      }
      return 0;
    });
  });
}

void add_fetch(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  auto output = std::make_shared<std::string>();
  auto frame = std::make_shared<std::optional<int64_t>>();
  auto all = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "fetch", "Download a job's current or final EXR (and a PNG preview beside it)");
  cmd->add_option("job", *job, "Job id, or a sequence's (its frames with --frame or --all)")
      ->required();
  cmd->add_option(
         "-o,--output", *output,
         "Output: x.exr (and its PNG preview x.png beside it) or x.png (the preview alone); for a "
         "sequence's frames a '#' run or %04d in the name takes the frame number (default: "
         ".NNNN before the extension); a sequence without --frame/--all: x.png its contact "
         "sheet, x.mp4 its movie")
      ->required();
  CLI::Option* one =
      cmd->add_option("--frame", *frame, "A sequence: the image of this frame (done or not)");
  cmd->add_flag("--all", *all, "A sequence: the image of every frame that is done")->excludes(one);
  add_client_options(cmd, *args);
  cmd->callback([args, job, output, frame, all, &exit_code] {
    exit_code = guarded("fetch", [&] {
      const OutputFormat format = check_output_path(*output, /*movie=*/true);
      if (format == OutputFormat::kMp4 && (*all || frame->has_value())) {
        throw std::invalid_argument("-o " + *output +
                                    ": a sequence's frames are images (.exr or .png); its movie "
                                    "is fetched without --frame or --all");
      }
      FarmClient client(*args);
      if (*all || frame->has_value()) {
        for (const std::string& line : fetch_frames(client, *job, *output, format, *frame)) {
          std::cout << line << "\n";
        }
        return 0;
      }
      std::cout << fetch_image(client, *job, *output, format) << "\n";
      return 0;
    });
  });
}

}  // namespace rayfarm::cli

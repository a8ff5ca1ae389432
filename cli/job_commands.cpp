// status, list, cancel, pause, resume, set-priority, rm and retry: one request about one job (or
// all of them) and its answer.
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "cli/farm_client.h"
#include "cli/farm_commands.h"
#include "cli/farm_output.h"
#include "common/limits.h"
#include "common/protocol/convert.h"

namespace rayfarm::cli {
using protocol::encode;

void add_status(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto detail = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand("status", "Show one job in detail, or every job");
  cmd->add_option("job", *job, "Job id (default: every job)");
  add_client_options(cmd, *args);
  cmd->add_flag("--json", *json, "One JSON object (per job, one a line)");
  cmd->add_flag("--detail", *detail,
                "With a job: also its units (leased now, failed or retried, the latest merged; "
                "worker, time, retries), what each worker did, and the job's log");
  cmd->callback([args, job, json, detail, &exit_code] {
    exit_code = guarded("status", [&] {
      if (*detail && job->empty()) {
        throw CLI::ValidationError("--detail", "needs a job id: rayfarm status JOB --detail");
      }
      FarmClient client(*args);
      if (*detail) {
        wire::JobDetailRequest request;
        request.set_job_id(*job);
        const auto d = client.call<wire::JobDetail>(encode(std::move(request)));
        if (*json) {
          print_json(detail_json(d));
        } else {
          print_detail(d);
        }
      } else if (job->empty()) {
        const auto list = client.call<wire::JobList>(encode(wire::ListJobs{}));
        if (*json) {
          for (const auto& st : list.jobs()) print_json(status_json(st));
        } else {
          print_table(list);
        }
      } else if (*json) {
        print_json(status_json(query_status(client, *job)));
      } else {
        print_status(for_people(query_status(client, *job)));
      }
      return 0;
    });
  });
}

void add_list(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand("list", "List the farm's jobs");
  add_client_options(cmd, *args);
  cmd->add_flag("--json", *json, "One JSON object per job, one a line");
  cmd->callback([args, json, &exit_code] {
    exit_code = guarded("list", [&] {
      FarmClient client(*args);
      const auto list = client.call<wire::JobList>(encode(wire::ListJobs{}));
      if (*json) {
        for (const auto& st : list.jobs()) print_json(status_json(st));
      } else {
        print_table(list);
      }
      return 0;
    });
  });
}

namespace {

/// A command that sends one request about one job and prints the line `say` makes of the reply.
template <class Request, class Reply>
void add_job_action(CLI::App& app, int& exit_code, const char* name, const std::string& help,
                    std::string (*say)(const Reply&)) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(name, help);
  cmd->add_option("job", *job, "Job id")->required();
  add_client_options(cmd, *args);
  cmd->callback([args, job, name, say, &exit_code] {
    exit_code = guarded(name, [&] {
      FarmClient client(*args);
      Request request;
      request.set_job_id(*job);
      std::cout << say(client.call<Reply>(encode(std::move(request))));
      return 0;
    });
  });
}

}  // namespace

void add_cancel(CLI::App& app, int& exit_code) {
  add_job_action<wire::CancelJob, wire::CancelReply>(
      app, exit_code, "cancel", "Cancel a job; its image keeps the samples merged so far",
      [](const wire::CancelReply& reply) {
        return fmt::format("job {} {}\n", reply.job_id(), protocol::job_state_name(reply.state()));
      });
}

namespace {

std::string say_change(const wire::ChangeJobReply& reply) {
  return fmt::format("job {} {}{}, priority {}\n", reply.job_id(),
                     protocol::job_state_name(reply.state()), reply.paused() ? ", paused" : "",
                     reply.priority());
}

/// Sends one ChangeJob (its job id set here) and prints the reply.
void add_change(int& exit_code, CLI::App* cmd, std::shared_ptr<ClientArgs> args,
                std::shared_ptr<std::string> job, std::function<void(wire::ChangeJob&)> fill) {
  const std::string name = cmd->get_name();
  cmd->callback([args, job, name, fill, &exit_code] {
    exit_code = guarded(name.c_str(), [&] {
      FarmClient client(*args);
      wire::ChangeJob request;
      request.set_job_id(*job);
      fill(request);
      std::cout << say_change(client.call<wire::ChangeJobReply>(encode(std::move(request))));
      return 0;
    });
  });
}

void add_pause_like(CLI::App& app, int& exit_code, const char* name, const std::string& help,
                    bool paused) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(name, help);
  cmd->add_option("job", *job, "Job id")->required();
  add_client_options(cmd, *args);
  add_change(exit_code, cmd, args, job,
             [paused](wire::ChangeJob& request) { request.set_paused(paused); });
}

}  // namespace

void add_pause(CLI::App& app, int& exit_code) {
  add_pause_like(app, exit_code, "pause",
                 "Pause a queued or running job: no more of its units go out (those out finish "
                 "and count) and its clock stops, until `rayfarm resume JOB`",
                 true);
  add_pause_like(app, exit_code, "resume", "Resume a paused job", false);
}

void add_set_priority(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ClientArgs>();
  auto job = std::make_shared<std::string>();
  auto priority = std::make_shared<int32_t>(0);
  CLI::App* cmd = app.add_subcommand(
      "set-priority",
      "Change a queued or running job's priority: higher runs first; jobs of equal priority "
      "share the workers");
  cmd->add_option("job", *job, "Job id")->required();
  cmd->add_option("priority", *priority,
                  "From " + std::to_string(kMinPriority) + " to " + std::to_string(kMaxPriority))
      ->required()
      ->check(CLI::Range(kMinPriority, kMaxPriority));
  add_client_options(cmd, *args);
  add_change(exit_code, cmd, args, job,
             [priority](wire::ChangeJob& request) { request.set_priority(*priority); });
}

void add_remove(CLI::App& app, int& exit_code) {
  add_job_action<wire::RemoveJob, wire::RemoveReply>(
      app, exit_code, "rm",
      "Remove a finished (done, failed or cancelled) job and its files from the master",
      [](const wire::RemoveReply& reply) {
        return fmt::format("job {} removed\n", reply.job_id());
      });
}

void add_retry(CLI::App& app, int& exit_code) {
  add_job_action<wire::RetryJob, wire::RetryReply>(
      app, exit_code, "retry",
      "Run a failed or cancelled job again from its first sample, under the same id",
      [](const wire::RetryReply& reply) {
        return fmt::format("job {} {}\n", reply.job_id(), protocol::job_state_name(reply.state()));
      });
}

}  // namespace rayfarm::cli

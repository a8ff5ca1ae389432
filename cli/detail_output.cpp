// `rayfarm status JOB --detail`: after the job's status, its units (leased now, then those that
// failed or were handed out again, then the latest merged), what each worker did, and the job's
// log; and the same as one JSON object.
#include <iostream>

#include <fmt/format.h>

#include "cli/farm_output.h"
#include "common/util/text.h"

namespace rayfarm::cli {

std::string worker_state(const wire::WorkerInfo& w) {
  if (w.control() == "disabled") return "disabled";
  // The master says "drained" once it holds no units (of any job, also those this key may not
  // see); an older master says "draining" throughout.
  if (w.control() == "drained") return "drained";
  if (w.control() == "draining") return w.units().empty() ? "drained" : "draining";
  return w.units().empty() ? "idle" : "busy";
}

void print_detail(const wire::JobDetail& d) {
  print_status(d.status());
  if (d.units_size() > 0 || d.units_queued() > 0) {
    std::cout << fmt::format(
        "\nunits      {} queued, {} handed out more than once, {} failed at least once\n",
        d.units_queued(), d.units_retried(), d.units_failed());
    std::cout << fmt::format("{:>7} {:<19} {:<11} {:<9} {:>8} {:>7}  {}\n", "UNIT", "TILE",
                             "SAMPLES", "STATE", "TIME", "RETRIES", "WORKER / ERROR");
    for (const wire::UnitInfo& u : d.units()) {
      std::string who;
      for (const std::string& w : u.workers()) who += (who.empty() ? "" : ", ") + w;
      if (!u.error().empty())
        who += (who.empty() ? "" : "; ") + std::string("failed: ") + u.error();
      std::cout << fmt::format(
          "{:>7} {:<19} {:<11} {:<9} {:>8} {:>7}  {}\n", u.unit_id(),
          fmt::format("{},{}-{},{}", u.tile().x0(), u.tile().y0(), u.tile().x1(), u.tile().y1()),
          fmt::format("{}-{}", u.sample_begin(), u.sample_end()), u.state(),
          u.state() == "queued" ? std::string("-") : format_duration(u.seconds()),
          u.leases() > 1 ? u.leases() - 1 : 0, who.empty() ? "-" : who);
    }
    if (d.units_left_out() > 0) {
      std::cout << fmt::format("{:>7} more merged units not listed\n", d.units_left_out());
    }
  }
  if (d.workers_size() > 0) {
    std::cout << fmt::format("\n{:<40} {:>8} {:>12} {:>8}\n", "WORKER", "UNITS", "RENDER TIME",
                             "FAILURES");
    for (const wire::JobWorkerShare& s : d.workers()) {
      std::cout << fmt::format("{:<40} {:>8} {:>12} {:>8}\n", s.worker().substr(0, 40),
                               s.units_done(), format_duration(s.render_seconds()), s.failures());
    }
  }
  std::cout << "\nlog\n";
  if (d.log_left_out() > 0)
    std::cout << fmt::format("  ({} earlier lines left out)\n", d.log_left_out());
  if (d.log_size() == 0) std::cout << "  (nothing yet)\n";
  for (const wire::JobLogLine& l : d.log()) {
    std::cout << fmt::format("  {} {:<7} {}\n", format_time(l.unix_ms()), l.level(), l.text());
  }
}

nlohmann::json detail_json(const wire::JobDetail& d) {
  nlohmann::json units = nlohmann::json::array();
  for (const wire::UnitInfo& u : d.units()) {
    units.push_back(
        {{"unit", u.unit_id()},
         {"tile", {u.tile().x0(), u.tile().y0(), u.tile().x1(), u.tile().y1()}},
         {"samples", {u.sample_begin(), u.sample_end()}},
         {"state", u.state()},
         {"workers", u.workers()},
         {"seconds", u.seconds()},
         {"leases", u.leases()},
         {"error", u.error().empty() ? nlohmann::json(nullptr) : nlohmann::json(u.error())}});
  }
  nlohmann::json workers = nlohmann::json::array();
  for (const wire::JobWorkerShare& s : d.workers()) {
    workers.push_back({{"worker", s.worker()},
                       {"units_done", s.units_done()},
                       {"render_seconds", s.render_seconds()},
                       {"failures", s.failures()}});
  }
  nlohmann::json log = nlohmann::json::array();
  for (const wire::JobLogLine& l : d.log()) {
    log.push_back({{"unix_ms", l.unix_ms()}, {"level", l.level()}, {"text", l.text()}});
  }
  nlohmann::json out = status_json(d.status());
  out["units"] = std::move(units);
  out["units_queued"] = d.units_queued();
  out["units_retried"] = d.units_retried();
  out["units_failed"] = d.units_failed();
  out["units_left_out"] = d.units_left_out();
  out["workers"] = std::move(workers);
  out["log"] = std::move(log);
  out["log_left_out"] = d.log_left_out();
  return out;
}

}  // namespace rayfarm::cli

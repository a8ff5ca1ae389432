// A job's detail view (`rayfarm status JOB --detail`, the page's job view): its units as the
// scheduler and the unit book (unit_book.h) know them, what each worker did, and its log
// (job_log.h).
#include <algorithm>
#include <map>

#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "master/job_manager.h"

namespace rayfarm::master {
namespace protocol = rayfarm::protocol;

namespace {

/// The most units one detail lists: those leased now first, then those that failed or were
/// leased again, then the latest merged.
constexpr size_t kDetailUnits = 200;

}  // namespace

void JobManager::note(JobRecord& record, const char* level, std::string text, bool routine) {
  const bool frame = !record.spec.sequence.empty();
  if (routine && frame) return;
  record.log.add(wall_ms(), level, std::move(text),
                 frame ? JobLog::kMaxFrameLines : JobLog::kMaxLines,
                 frame ? JobLog::kMaxFrameText : JobLog::kMaxText);
}

void JobManager::note_accepted(JobRecord& record, uint64_t units, const std::string& stop,
                               const std::vector<std::string>& warnings) {
  const JobSpec& spec = record.spec;
  note(record, "info",
       fmt::format("accepted{}: scene {}, {}x{}, {}, {}; {} units", record.paused ? " paused" : "",
                   spec.scene_path, spec.film.width, spec.film.height, stop,
                   integrator_name(spec.settings.integrator), units),
       /*routine=*/true);
  // The scene's warnings, the first few: the rest stay in the master's log.
  constexpr size_t kWarningsLogged = 8;
  for (size_t i = 0; i < warnings.size() && i < kWarningsLogged; ++i) {
    note(record, "warning", "the scene: " + warnings[i]);
  }
  if (warnings.size() > kWarningsLogged) {
    note(record, "warning",
         fmt::format("the scene: {} more warnings (the master's log has them)",
                     warnings.size() - kWarningsLogged));
  }
}

std::string JobManager::requester(const std::string& by) {
  return by.empty() ? "a client" : "key '" + protocol::printable(by) + "'";
}

std::optional<wire::JobDetail> JobManager::detail(const std::string& id,
                                                  uint32_t workers_total) const {
  auto st = status(id, workers_total);
  if (!st) return std::nullopt;
  wire::JobDetail out;
  *out.mutable_status() = std::move(*st);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return out;  // a sequence: its frames are in its status
  const Job& job = it->second;
  for (const JobLogLine& line : job.record.log.lines) {
    wire::JobLogLine* l = out.add_log();
    l->set_unix_ms(line.unix_ms);
    l->set_level(line.level);
    l->set_text(line.text);
  }
  out.set_log_left_out(job.record.log.left_out);
  if (!job.active) return out;
  const ActiveJob& a = *job.active;
  const UnitBook& book = a.book;
  const UnitGrid& grid = a.grid();
  const auto now = Clock::now();
  auto add_unit = [&](uint64_t first, uint32_t count, const char* state) {
    wire::UnitInfo* u = out.add_units();
    const UnitGrid::Unit unit = grid.unit(first);
    const SampleRange samples = grid.run_samples(first, count);
    u->set_unit_id(first);
    *u->mutable_tile() = protocol::rect_to_wire(unit.rect);
    u->set_sample_begin(samples.begin);
    u->set_sample_end(samples.end);
    u->set_state(state);
    return u;
  };

  // Leased now: one row per lease (a run of a tile's passes is one lease; a slow unit leased a
  // second time has two).
  struct Row {
    uint64_t first = 0;
    uint32_t count = 0;
    WorkerId worker;
    Clock::time_point since;
  };
  std::map<uint64_t, Row> leases;  // by lease serial
  for (const Scheduler::Holding& h : scheduler_.holdings(id, kDetailUnits * 4)) {
    auto [row, inserted] = leases.try_emplace(h.lease, Row{h.unit, 0, h.worker, h.since});
    row->second.first = std::min(row->second.first, h.unit);
    ++row->second.count;
  }
  std::vector<const Row*> rows;
  for (const auto& [serial, row] : leases) rows.push_back(&row);
  std::sort(rows.begin(), rows.end(),
            [](const Row* x, const Row* y) { return x->first < y->first; });
  for (const Row* row : rows) {
    if (static_cast<size_t>(out.units_size()) >= kDetailUnits) break;
    wire::UnitInfo* u = add_unit(row->first, row->count, "rendering");
    u->add_workers(name_of(row->worker));
    u->set_seconds(std::chrono::duration<double>(now - row->since).count());
    const auto open = book.open().find(row->first);
    if (open != book.open().end()) {
      u->set_leases(open->second.leases);
      u->set_error(open->second.error);
    }
  }
  // Handed out before, not merged, waiting again: failed, or taken back from a worker.
  std::vector<uint64_t> waiting;
  for (const auto& [unit, open] : book.open()) {
    if (!scheduler_.is_leased(UnitRef{id, unit}) && !a.merger.merged(unit)) {
      waiting.push_back(unit);
    }
  }
  std::sort(waiting.begin(), waiting.end());
  for (const uint64_t unit : waiting) {
    if (static_cast<size_t>(out.units_size()) >= kDetailUnits) break;
    const UnitBook::Open& open = book.open().at(unit);
    wire::UnitInfo* u = add_unit(unit, 1, "queued");
    u->set_leases(open.leases);
    u->set_error(open.error);
  }
  // Merged: those that needed more than one lease, then the latest; newest first.
  uint64_t listed_done = 0;
  for (const auto* done : {&book.troubled(), &book.recent()}) {
    for (auto d = done->rbegin(); d != done->rend(); ++d) {
      if (static_cast<size_t>(out.units_size()) >= kDetailUnits) break;
      wire::UnitInfo* u = add_unit(d->unit, d->units, "done");
      u->add_workers(d->worker);
      u->set_seconds(d->render_seconds);
      u->set_leases(d->leases);
      u->set_error(d->error);
      listed_done += d->units;
    }
  }
  const uint64_t merged = a.merger.merged_count();
  out.set_units_left_out(merged > listed_done ? merged - listed_done : 0);
  out.set_units_queued(scheduler_.counts(id).pending);
  out.set_units_retried(book.retried());
  out.set_units_failed(book.failed_units());
  for (const auto& [worker, share] : book.shares()) {
    wire::JobWorkerShare* s = out.add_workers();
    s->set_worker(worker);
    s->set_units_done(share.units_done);
    s->set_render_seconds(share.render_seconds);
    s->set_failures(share.failures);
  }
  return out;
}

}  // namespace rayfarm::master

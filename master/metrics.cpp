#include "master/metrics.h"

#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

namespace rayfarm::master {

Histogram::Histogram(std::vector<double> bounds) : bounds_(std::move(bounds)) {
  if (bounds_.size() > kMaxBuckets) throw std::logic_error("Histogram: too many buckets");
}

void Histogram::observe(double v) {
  if (!std::isfinite(v)) return;
  size_t i = 0;
  while (i < bounds_.size() && v > bounds_[i]) ++i;
  counts_[i].fetch_add(1, std::memory_order_relaxed);
  sum_.fetch_add(v, std::memory_order_relaxed);
}

uint64_t Histogram::cumulative(size_t i) const {
  uint64_t n = 0;
  for (size_t j = 0; j <= i && j <= bounds_.size(); ++j) n += counts_[j].load(std::memory_order_relaxed);
  return n;
}

void CounterFamily::add(const std::string& label, double v) {
  std::lock_guard lock(mutex_);
  values_[label] += v;
}

std::map<std::string, double> CounterFamily::values() const {
  std::lock_guard lock(mutex_);
  return values_;
}

Metrics& metrics() {
  static Metrics m;
  return m;
}

namespace {

/// A sample value as Prometheus reads it: integers without a fraction, others in full precision.
std::string number(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  if (v == std::floor(v) && std::fabs(v) < 1e15) return fmt::format("{:.0f}", v);
  return fmt::format("{}", v);
}

/// A label value with \, " and newlines escaped.
std::string label_value(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '\\') out += "\\\\";
    else if (c == '"') out += "\\\"";
    else if (c == '\n') out += "\\n";
    else out += c;
  }
  return out;
}

}  // namespace

void PrometheusText::head(const std::string& name, const std::string& type,
                          const std::string& help) {
  out_ += "# HELP " + name + " " + help + "\n# TYPE " + name + " " + type + "\n";
}

void PrometheusText::counter(const std::string& name, const std::string& help, double value) {
  head(name, "counter", help);
  out_ += name + " " + number(value) + "\n";
}

void PrometheusText::gauge(const std::string& name, const std::string& help, double value) {
  head(name, "gauge", help);
  out_ += name + " " + number(value) + "\n";
}

void PrometheusText::family(const std::string& name, const std::string& type,
                            const std::string& help, const std::string& label,
                            const std::map<std::string, double>& values) {
  head(name, type, help);
  for (const auto& [value, v] : values) {
    out_ += fmt::format("{}{{{}=\"{}\"}} {}\n", name, label, label_value(value), number(v));
  }
}

void PrometheusText::histogram(const std::string& name, const std::string& help,
                               const Histogram& h) {
  head(name, "histogram", help);
  const auto& bounds = h.bounds();
  for (size_t i = 0; i < bounds.size(); ++i) {
    out_ += fmt::format("{}_bucket{{le=\"{}\"}} {}\n", name, number(bounds[i]), h.cumulative(i));
  }
  const uint64_t count = h.cumulative(bounds.size());
  out_ += fmt::format("{}_bucket{{le=\"+Inf\"}} {}\n", name, count);
  out_ += name + "_sum " + number(h.sum()) + "\n";
  out_ += fmt::format("{}_count {}\n", name, count);
}

void PrometheusText::metrics(const Metrics& m) {
  counter("rayfarm_units_leased_total", "Leases of units handed to workers.", m.units_leased.value());
  counter("rayfarm_units_merged_total", "Unit results merged into their job's image.",
          m.units_merged.value());
  counter("rayfarm_units_duplicated_total",
          "Unit results dropped because the unit was merged before.", m.units_duplicate.value());
  counter("rayfarm_units_rejected_total", "Unit results refused as malformed or implausible.",
          m.units_rejected.value());
  counter("rayfarm_units_unleased_total",
          "Unit results for units never leased to their sender, dropped.",
          m.units_unleased.value());
  family("rayfarm_units_discarded_total", "counter",
         "Unit results dropped as routine: late for a job that was cancelled or failed.", "reason",
         {{"job_finished", m.units_discarded_job_finished.value()}});
  counter("rayfarm_units_requeued_total",
          "Leased units taken back and queued again (worker lost or gone, unit failed).",
          m.units_requeued.value());
  counter("rayfarm_units_failed_total", "Units a worker reported it could not render.",
          m.units_failed.value());
  counter("rayfarm_samples_merged_total", "Pixel samples merged.", m.samples_merged.value());
  gauge("rayfarm_workers_connected", "Workers connected now.", m.workers_connected.value());
  counter("rayfarm_workers_joined_total", "Workers that said hello.", m.workers_joined.value());
  counter("rayfarm_workers_lost_total", "Workers declared lost after a silent liveness window.",
          m.workers_lost.value());
  counter("rayfarm_workers_left_total",
          "Workers that left, were refused or disconnected (not lost).", m.workers_left.value());
  family("rayfarm_received_bytes_total", "counter", "Bytes received on each socket.", "socket",
         {{"worker", m.worker_bytes_received.value()},
          {"client", m.client_bytes_received.value()}});
  counter("rayfarm_client_requests_total", "Requests received on the client socket.",
          m.client_requests.value());
  histogram("rayfarm_merge_seconds", "Time the reactor took to check and merge one result.",
            m.merge_seconds);
  histogram("rayfarm_unit_seconds", "Render time of each merged result, as its worker reports it.",
            m.unit_seconds);
  histogram("rayfarm_checkpoint_seconds", "Time to write one checkpoint.", m.checkpoint_seconds);
  histogram("rayfarm_image_write_seconds",
            "Time to write one progressive image with its preview and error record.",
            m.image_write_seconds);
  family("rayfarm_refusals_total", "counter", "Refused connections, messages and requests.",
         "reason", m.refusals.values());
  family("rayfarm_http_responses_total", "counter", "HTTP responses by status code.", "code",
         m.http_responses.values());
  counter("rayfarm_reactor_busy_seconds_total",
          "Wall time the master's reactor thread spent working (not waiting); its rate is the "
          "reactor's busy fraction.",
          m.reactor_busy_seconds.value());
}

}  // namespace rayfarm::master

#pragma once
// The master's counters for Prometheus (GET /metrics on the HTTP endpoint, http_server.h): what
// the reactor, the ZAP handler and the writer threads count, kept in relaxed atomics so that
// counting costs a few nanoseconds and a scrape never takes a lock the reactor waits on.
// One set per process (metrics()): a master is one process.
#include <array>
#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace rayfarm::master {

/// A monotonically increasing count.
class Counter {
 public:
  void add(double v = 1.0) { value_.fetch_add(v, std::memory_order_relaxed); }
  double value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> value_{0.0};
};

/// A value that goes up and down.
class Gauge {
 public:
  void set(double v) { value_.store(v, std::memory_order_relaxed); }
  double value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> value_{0.0};
};

/// Observations counted into fixed buckets (upper bounds, ascending), with their sum.
class Histogram {
 public:
  static constexpr size_t kMaxBuckets = 16;
  explicit Histogram(std::vector<double> bounds);
  void observe(double v);
  const std::vector<double>& bounds() const { return bounds_; }
  /// Observations at most bounds()[i] (cumulative, as Prometheus counts them); i == bounds().size()
  /// is every observation.
  uint64_t cumulative(size_t i) const;
  double sum() const { return sum_.load(std::memory_order_relaxed); }

 private:
  std::vector<double> bounds_;
  std::array<std::atomic<uint64_t>, kMaxBuckets + 1> counts_{};  // per bucket, not cumulative
  std::atomic<double> sum_{0.0};
};

/// Counters told apart by one label's value (a refusal's reason). Values come from a small fixed
/// set in the code, never from a peer, so the family stays small.
class CounterFamily {
 public:
  void add(const std::string& label, double v = 1.0);
  std::map<std::string, double> values() const;

 private:
  mutable std::mutex mutex_;
  std::map<std::string, double> values_;
};

struct Metrics {
  // Units of work.
  Counter units_leased;     // leases handed to workers (a run of passes counts once)
  Counter units_merged;     // results merged
  Counter units_duplicate;  // results dropped: merged before (a straggler's twin)
  Counter units_rejected;   // results refused as malformed or implausible
  Counter units_unleased;   // results for units never leased to their sender
  // Results dropped as routine: late for a job that was cancelled or failed meanwhile (the
  // reason "job_finished" of rayfarm_units_discarded_total).
  Counter units_discarded_job_finished;
  Counter units_requeued;   // leases taken back (worker lost or gone, unit failed)
  Counter units_failed;     // UnitFailed reports
  Counter samples_merged;   // pixel samples merged
  // Workers.
  Gauge workers_connected;
  Counter workers_joined;
  Counter workers_lost;  // silent for their liveness window
  Counter workers_left;  // said goodbye, were refused or disconnected
  // Traffic.
  Counter worker_bytes_received;
  Counter client_bytes_received;
  Counter client_requests;
  // Timings.
  Histogram merge_seconds{{1e-4, 3e-4, 1e-3, 3e-3, 0.01, 0.03, 0.1, 0.3, 1.0}};
  Histogram unit_seconds{{0.1, 0.25, 0.5, 1, 2, 4, 8, 16, 32, 64, 128}};
  Histogram checkpoint_seconds{{0.01, 0.03, 0.1, 0.3, 1, 3, 10, 30}};
  Histogram image_write_seconds{{0.01, 0.03, 0.1, 0.3, 1, 3, 10, 30}};
  // Refused: connections (ZAP), messages of another protocol version, submissions, HTTP tokens.
  CounterFamily refusals;
  // HTTP requests by status code.
  CounterFamily http_responses;
  Counter reactor_busy_seconds;
};

/// The process's metrics.
Metrics& metrics();

/// Writes the Prometheus text format (version 0.0.4) of the lines below, one family at a time.
class PrometheusText {
 public:
  void counter(const std::string& name, const std::string& help, double value);
  void gauge(const std::string& name, const std::string& help, double value);
  /// A gauge or counter family with one label.
  void family(const std::string& name, const std::string& type, const std::string& help,
              const std::string& label, const std::map<std::string, double>& values);
  void histogram(const std::string& name, const std::string& help, const Histogram& h);
  /// Every counter of `m`.
  void metrics(const Metrics& m);
  const std::string& text() const { return out_; }

 private:
  std::string out_;
  void head(const std::string& name, const std::string& type, const std::string& help);
};

}  // namespace rayfarm::master

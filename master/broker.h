#pragma once
// The master's reactor: one thread owns both ROUTER sockets (workers, clients) and every timer.
// Workers say Hello, ask for work (WorkRequest) and get one unit per request; heartbeats flow both
// ways every interval; a worker silent for its liveness window is declared lost and its leased
// units are requeued. Clients send one request at a time and get one reply. Garbage on either
// socket is logged and ignored; a peer speaking another protocol version gets a Refusal.
#include <atomic>
#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "common/net/socket.h"
#include "common/protocol/heartbeat.h"
#include "master/job_manager.h"
#include "master/job_store.h"

namespace rayfarm::master {

struct MasterOptions {
  std::string worker_endpoint = "tcp://*:5555";
  std::string client_endpoint = "tcp://*:5556";
  std::filesystem::path data_dir = "rayfarm-data";
  protocol::HeartbeatOptions heartbeat;
  /// While results arrive, a job's image is rewritten at least this often.
  std::chrono::milliseconds image_interval{3000};
};

class Broker {
 public:
  /// Opens the data dir, reloads its jobs and binds both endpoints. Throws std::runtime_error
  /// (net::NetError for an endpoint) naming the cause.
  explicit Broker(MasterOptions options);
  ~Broker();
  Broker(const Broker&) = delete;
  Broker& operator=(const Broker&) = delete;

  /// Serves until `stop` becomes true (checked at least every 100 ms).
  void run(const std::atomic<bool>& stop);

  /// The bound endpoints, with the ports chosen for "tcp://*:0".
  std::string worker_endpoint() const { return workers_socket_.endpoint(); }
  std::string client_endpoint() const { return clients_socket_.endpoint(); }

 private:
  using Clock = std::chrono::steady_clock;
  struct Worker {
    std::string name;
    uint32_t threads = 0;
    Clock::time_point expires;  // declared lost when silent until then
    uint32_t wants = 0;         // WorkRequests not answered yet
    uint64_t units_sent = 0;
  };

  MasterOptions options_;
  JobStore store_;
  JobManager jobs_;
  net::Router workers_socket_;
  net::Router clients_socket_;
  std::map<net::PeerId, Worker> workers_;
  Clock::time_point next_heartbeat_;

  void handle_worker(const net::Delivery& delivery);
  void handle_client(const net::Delivery& delivery);
  void register_worker(const net::PeerId& peer, const wire::Hello& hello);
  void remove_worker(const net::PeerId& peer, const std::string& why);
  void dispatch();
  void send_worker(const net::PeerId& peer, const net::Frames& frames);
  void reply(const net::PeerId& peer, const net::Frames& frames);
  void on_timers();
  std::string worker_label(const net::PeerId& peer) const;
};

}  // namespace rayfarm::master

#pragma once
// The worker's scene bundles: a folder per bundle under the cache dir (<cache>/<hash>/), and the
// units waiting for a bundle the worker lacks. One bundle is asked of the master at a time; the
// master may say to ask again later, and the units keep waiting until then. The reactor sends
// what this asks for and hands it the replies; nothing here touches a socket.
#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "proto/rayfarm.pb.h"

namespace rayfarm::worker {

class BundleCache {
 public:
  using Clock = std::chrono::steady_clock;

  /// Creates the cache dir; throws std::runtime_error when it cannot.
  explicit BundleCache(std::filesystem::path dir);

  const std::filesystem::path& dir() const { return dir_; }
  /// Whether the bundle is unpacked in the cache (a cache folder is complete or absent).
  bool has(const std::string& hash) const;

  /// Parks a unit until its bundle arrives (the reactor then asks for it: next_request()).
  void wait_for(wire::WorkUnit unit);
  /// Units waiting for a bundle.
  size_t waiting() const { return waiting_.size(); }
  /// Whether units wait for a bundle that nobody has asked for yet (the master said to ask later).
  bool request_due() const { return !waiting_.empty() && requested_.empty(); }

  /// The hash to ask the master for now: the first waiting unit's, unless a request is out or the
  /// master said to ask later and that time has not come. Marks it asked for.
  std::optional<std::string> next_request();

  /// What a BundleReply means for the waiting units.
  struct Arrival {
    bool expected = false;  ///< false: a reply to no request of this worker's; nothing changed
    bool later = false;     ///< the master sends it later: the units keep waiting
    std::vector<wire::WorkUnit> units;  ///< the units that waited for it: to render, or to fail
    std::string error;                  ///< why they fail; "" when the bundle is cached
  };
  /// Unpacks the bundle of a reply into the cache and hands back the units that waited for it.
  Arrival on_reply(const wire::BundleReply& reply);

  /// Forgets the waiting units and the request out (a master that forgot this worker will not
  /// answer it; the units come again when asked for).
  void forget_requests();

 private:
  std::filesystem::path dir_;
  std::vector<wire::WorkUnit> waiting_;  // units waiting for their bundle
  std::string requested_;                // the hash asked for, "" when none
  Clock::time_point retry_{};            // the master said to ask again after this
};

}  // namespace rayfarm::worker

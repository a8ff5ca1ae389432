#pragma once
// The key options of a peer of the master (a worker, or the CLI's farm commands): --key,
// --master-key and --insecure, and the CURVE settings they give.
#include <stdexcept>
#include <string>

#include <CLI/CLI.hpp>

#include "common/net/keys.h"
#include "common/net/socket.h"

namespace rayfarm::net {

struct PeerKeyOptions {
  std::string key;         ///< this peer's secret key file, or the Z85 secret key
  std::string master_key;  ///< the master's public key file, or the Z85 key
  bool insecure = false;
};

/// Adds --key (env RAYFARM_KEY), --master-key (env RAYFARM_MASTER_KEY) and --insecure to `app`;
/// `peer` says whose key it is in the help ("worker", "client").
inline void add_peer_key_options(CLI::App& app, PeerKeyOptions& options, const std::string& peer) {
  app.add_option("--key", options.key,
                 "this " + peer +
                     "'s secret key file (NAME.key_secret from rayfarm keygen), or the Z85 secret "
                     "key")
      ->envname("RAYFARM_KEY");
  app.add_option("--master-key", options.master_key,
                 "the master's public key: its NAME.key file or the Z85 key")
      ->envname("RAYFARM_MASTER_KEY");
  app.add_flag("--insecure", options.insecure,
               "plain socket, no authentication or encryption: only to a master on loopback "
               "started with --insecure");
}

/// The CURVE settings of a Dealer towards the master: none with --insecure (the caller checks the
/// endpoint is on loopback), else this peer's key pair and the master's public key. Throws naming
/// what is missing or unreadable; `who` starts the message ("the worker", "this client").
inline Curve peer_curve(const PeerKeyOptions& options, const std::string& who) {
  if (options.insecure) return {};
  if (options.key.empty() || options.master_key.empty()) {
    throw std::runtime_error(
        who +
        " needs its key pair and the master's public key: --key FILE (from `rayfarm keygen`) and "
        "--master-key FILE|KEY, or RAYFARM_KEY and RAYFARM_MASTER_KEY; --insecure only for a "
        "master on loopback started with --insecure");
  }
  require_curve();
  const KeyPair pair = key_pair_from(options.key, "--key");
  Curve curve;
  curve.public_key = pair.public_key;
  curve.secret_key = pair.secret_key;
  curve.server_key = public_key_from(options.master_key, "--master-key");
  return curve;
}

}  // namespace rayfarm::net

// A server socket in a process of its own, for tests of what a client is told about a handshake
// with another process (as a CLI or worker is, with the master): `net_test_peer curve` binds a
// CURVE Router on 127.0.0.1 that admits every key, `net_test_peer plain` a plain one. It writes
// "ENDPOINT SERVER_PUBLIC_KEY" (the key "-" when plain) as its first line and serves until killed.
#include <chrono>
#include <iostream>
#include <memory>
#include <string>

#include "common/net/keys.h"
#include "common/net/socket.h"
#include "common/net/zap.h"

int main(int argc, char** argv) {
  using namespace rayfarm::net;
  const bool curve = argc > 1 && std::string(argv[1]) == "curve";
  KeyPair keys;
  std::unique_ptr<ZapHandler> zap;
  Curve settings;
  if (curve) {
    keys = generate_key_pair();
    zap = std::make_unique<ZapHandler>([](const ZapRequest&) { return ZapVerdict{true, "peer"}; });
    settings = {keys.public_key, keys.secret_key, "", "peers"};
  }
  Router router("tcp://127.0.0.1:0", kDefaultMaxMessageBytes, settings);
  std::cout << router.endpoint() << " " << (curve ? keys.public_key : "-") << std::endl;
  while (true) router.receive(std::chrono::milliseconds{1000});
}

// The broker's gate, in one process: plain sockets only on loopback; no start without its ZAP
// handler or its allow-lists; with CURVE, a worker key gets in on the worker socket only and a
// client key on the client socket only; a submission over a limit gets a refusal naming it.
#include <gtest/gtest.h>

#include <thread>

#include "common/bundle/bundle.h"
#include "common/net/zap.h"
#include "common/protocol/codec.h"
#include "common/protocol/convert.h"
#include "master/broker.h"
#include "tests/master/broker_peer.h"
#include "tests/support/handshake.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {
namespace fs = std::filesystem;
using std::chrono::milliseconds;
using testing::TempDir;

class BrokerSecurityTest : public ::testing::Test {
 protected:
  TempDir dir;
  net::KeyPair master_keys = net::generate_key_pair();
  net::KeyPair worker_keys = net::generate_key_pair();
  net::KeyPair client_keys = net::generate_key_pair();

  MasterOptions secure_options() {
    net::write_key_pair(dir.path() / "workers", "w1", worker_keys);
    net::write_key_pair(dir.path() / "clients", "c1", client_keys);
    MasterOptions o;
    o.worker_endpoint = "tcp://127.0.0.1:0";
    o.client_endpoint = "tcp://127.0.0.1:0";
    o.data_dir = dir.path() / "data";
    o.security.key = master_keys;
    o.security.worker_keys = dir.path() / "workers";
    o.security.client_keys = dir.path() / "clients";
    return o;
  }

  net::Curve as_peer(const net::KeyPair& keys) const {
    return {keys.public_key, keys.secret_key, master_keys.public_key, ""};
  }
};

using test_peer::next;

net::Frames hello(wire::Role role) { return protocol::encode(test_peer::hello(role)); }

TEST_F(BrokerSecurityTest, PlainSocketsOnlyOnLoopback) {
  MasterOptions o;
  o.data_dir = dir.path() / "data";
  o.worker_endpoint = "tcp://*:0";
  o.client_endpoint = "tcp://127.0.0.1:0";
  try {
    Broker broker(o);
    FAIL() << "an insecure master bound a public endpoint";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("--insecure is allowed only on loopback endpoints, and "
                                         "tcp://*:0 is reachable from other machines"),
              std::string::npos)
        << e.what();
  }
  o.worker_endpoint = "tcp://127.0.0.1:0";
  EXPECT_NO_THROW(Broker{o});
}

TEST_F(BrokerSecurityTest, NoStartWithoutTheZapHandlerOrTheAllowLists) {
  MasterOptions o = secure_options();
  {
    net::ZapHandler squatter([](const net::ZapRequest&) { return net::ZapVerdict{true, ""}; });
    try {
      Broker broker(o);
      FAIL() << "the master started without its own ZAP handler";
    } catch (const net::NetError& e) {
      EXPECT_NE(std::string(e.what()).find("cannot authenticate its peers"), std::string::npos)
          << e.what();
    }
  }
  o.security.client_keys = dir.path() / "missing";
  try {
    Broker broker(o);
    FAIL() << "the master started without its client allow-list";
  } catch (const net::KeyError& e) {
    EXPECT_NE(std::string(e.what()).find("missing"), std::string::npos) << e.what();
  }
  o.security.client_keys.clear();
  EXPECT_THROW(Broker{o}, net::KeyError);
}

TEST_F(BrokerSecurityTest, EachKeyGetsInOnlyThroughItsOwnSocket) {
  MasterOptions o = secure_options();
  o.limits.max_spp = 100;
  Broker broker(o);
  std::atomic<bool> stop{false};
  std::thread reactor([&] { broker.run(stop); });

  net::Dealer worker(broker.worker_endpoint(), net::kDefaultMaxMessageBytes, as_peer(worker_keys));
  worker.send(hello(wire::ROLE_WORKER));
  auto welcome = next(worker);
  ASSERT_TRUE(welcome);
  EXPECT_TRUE(welcome->as<wire::Welcome>()) << welcome->type;

  net::Dealer client(broker.client_endpoint(), net::kDefaultMaxMessageBytes, as_peer(client_keys));
  client.send(hello(wire::ROLE_CLIENT));
  ASSERT_TRUE(next(client));

  // A worker's key cannot submit, a client's key cannot take work, a stranger's neither.
  net::KeyPair stranger = net::generate_key_pair();
  for (auto [endpoint, keys] : {std::pair{broker.client_endpoint(), &worker_keys},
                                std::pair{broker.worker_endpoint(), &client_keys},
                                std::pair{broker.worker_endpoint(), &stranger}}) {
    net::Dealer intruder(endpoint, net::kDefaultMaxMessageBytes, as_peer(*keys));
    intruder.send(hello(wire::ROLE_CLIENT));
    EXPECT_EQ(testing::settled(intruder).state, net::Handshake::kRefused) << endpoint;
    EXPECT_FALSE(next(intruder, milliseconds{200}));
  }

  // Over a limit: a refusal naming it, and the master still answers.
  wire::SubmitJob submit;
  protocol::bundle_to_wire(
      make_bundle({{"scene.json", "{\"film\": {\"width\": 8, \"height\": 8}}"}}),
      submit.mutable_bundle());
  submit.set_scene_path("scene.json");
  submit.mutable_overrides()->set_spp(1000);
  client.send(protocol::encode(submit));
  auto reply = next(client);
  ASSERT_TRUE(reply && reply->as<wire::SubmitReply>());
  EXPECT_NE(reply->as<wire::SubmitReply>()->error().find("100 spp (--max-spp)"), std::string::npos)
      << reply->as<wire::SubmitReply>()->error();
  client.send(protocol::encode(wire::ListJobs{}));
  reply = next(client);
  ASSERT_TRUE(reply && reply->as<wire::JobList>());

  stop = true;
  reactor.join();
}

}  // namespace
}  // namespace rayfarm::master

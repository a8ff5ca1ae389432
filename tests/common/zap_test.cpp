// CURVE sockets and the ZAP handler, in one process on loopback: a listed key gets through with
// its name as User-Id; an unlisted key, a key of the other domain, a wrong server key and a plain
// socket against a CURVE one are all kept out, and the Dealer says why. Every wait is bounded.
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <sstream>
#include <thread>

#include "common/net/context.h"
#include "common/net/keys.h"
#include "common/net/socket.h"
#include "common/net/zap.h"
#include "tests/e2e/process.h"
#include "tests/support/handshake.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::net {
namespace {

using std::chrono::milliseconds;
using testing::settled;
using testing::TempDir;

class CurveTest : public ::testing::Test {
 protected:
  TempDir dir;
  KeyPair server = generate_key_pair();
  KeyPair worker = generate_key_pair();
  KeyPair client = generate_key_pair();

  void SetUp() override {
    write_key_pair(dir.path() / "workers", "worker-1", worker);
    write_key_pair(dir.path() / "clients", "alice", client);
  }

  Curve server_curve(const std::string& domain) const {
    return {server.public_key, server.secret_key, "", domain};
  }
  Curve client_curve(const KeyPair& keys, const std::string& server_key) const {
    return {keys.public_key, keys.secret_key, server_key, ""};
  }
  AllowListPolicy policy(milliseconds reload = milliseconds{1000}) const {
    return AllowListPolicy(
        {{"workers", dir.path() / "workers"}, {"clients", dir.path() / "clients"}}, reload);
  }
};

TEST_F(CurveTest, AListedKeyGetsThroughNamedAndOthersAreRefused) {
  AllowListPolicy allow = policy();
  std::vector<ZapRequest> refused;
  std::mutex mutex;
  ZapHandler zap([&](const ZapRequest& r) {
    const auto d = allow.decide(r);
    if (!d.admitted) {
      std::lock_guard lock(mutex);
      refused.push_back(r);
    }
    return ZapVerdict{d.admitted, d.name};
  });
  Router router("tcp://127.0.0.1:0", kDefaultMaxMessageBytes, server_curve("workers"));

  Dealer good(router.endpoint(), kDefaultMaxMessageBytes, client_curve(worker, server.public_key));
  ASSERT_TRUE(good.send({"hello"}));
  const auto delivery = router.receive(milliseconds{5000});
  ASSERT_TRUE(delivery);
  EXPECT_EQ(delivery->frames, Frames{"hello"});
  EXPECT_EQ(delivery->user, "worker-1");
  EXPECT_EQ(good.handshake().state, Handshake::kSucceeded);
  ASSERT_TRUE(router.send(delivery->peer, {"welcome"}));
  EXPECT_EQ(good.receive(milliseconds{5000}), std::optional<Frames>(Frames{"welcome"}));

  // A client key on the workers' socket, and a key nobody listed: refused, and they are told.
  for (const KeyPair* keys : {&client, &server}) {
    Dealer bad(router.endpoint(), kDefaultMaxMessageBytes, client_curve(*keys, server.public_key));
    bad.send({"let me in"});
    const HandshakeStatus st = settled(bad);
    EXPECT_EQ(st.state, Handshake::kRefused) << st.detail;
    EXPECT_NE(st.detail.find("authentication refused"), std::string::npos) << st.detail;
  }
  EXPECT_FALSE(router.receive(milliseconds{200}));  // nothing of theirs arrived
  std::lock_guard lock(mutex);
  ASSERT_GE(refused.size(), 2u);
  EXPECT_EQ(refused[0].address, "127.0.0.1");
  EXPECT_EQ(refused[0].domain, "workers");
  EXPECT_EQ(refused[0].key, client.public_key);
  EXPECT_GE(zap.refusals(), 2u);
}

TEST_F(CurveTest, DomainsKeepWorkersAndClientsApart) {
  AllowListPolicy allow = policy();
  ZapRequest r{"clients", "10.0.0.7", "CURVE", worker.public_key};
  const auto d = allow.decide(r);
  EXPECT_FALSE(d.admitted);
  EXPECT_NE(d.reason.find("not on the clients allow-list"), std::string::npos) << d.reason;
  EXPECT_NE(d.reason.find("workers key 'worker-1'"), std::string::npos) << d.reason;
  r.key = client.public_key;
  EXPECT_TRUE(allow.decide(r).admitted);
  EXPECT_EQ(allow.decide(r).name, "alice");
  r.domain = "";  // a socket without a domain is never admitted
  EXPECT_FALSE(allow.decide(r).admitted);
  r.domain = "clients";
  r.mechanism = "NULL";
  r.key.clear();
  EXPECT_FALSE(allow.decide(r).admitted);
}

TEST_F(CurveTest, AKeyAddedToTheFolderIsAdmittedWithoutARestart) {
  AllowListPolicy allow = policy(milliseconds{0});
  const KeyPair late = generate_key_pair();
  const ZapRequest r{"workers", "127.0.0.1", "CURVE", late.public_key};
  EXPECT_FALSE(allow.decide(r).admitted);
  write_key_pair(dir.path() / "workers", "late", late);
  const auto d = allow.decide(r);
  EXPECT_TRUE(d.admitted);
  EXPECT_NE(d.reload_note.find("2 keys (was 1)"), std::string::npos) << d.reload_note;
  std::filesystem::remove(dir.path() / "workers" / "late.key");
  EXPECT_FALSE(allow.decide(r).admitted);
  EXPECT_FALSE(d.reload_warning) << d.reload_note;
}

TEST_F(CurveTest, ABrokenFileInTheFolderDoesNotHoldBackARevocation) {
  const KeyPair a = generate_key_pair(), b = generate_key_pair();
  write_key_pair(dir.path() / "workers", "a", a);
  write_key_pair(dir.path() / "workers", "b", b);
  AllowListPolicy allow = policy(milliseconds{0});
  const auto as = [](const KeyPair& keys) {
    return ZapRequest{"workers", "127.0.0.1", "CURVE", keys.public_key};
  };
  ASSERT_TRUE(allow.decide(as(a)).admitted);
  ASSERT_TRUE(allow.decide(as(b)).admitted);

  // At the same time: b's key is removed, and a file that is not a key is dropped in.
  std::filesystem::remove(dir.path() / "workers" / "b.key");
  dir.write("workers/broken.key", "nonsense\n");
  const auto first = allow.decide(as(b));
  EXPECT_FALSE(first.admitted) << "a revoked key was admitted: " << first.reload_note;
  EXPECT_TRUE(first.reload_warning) << first.reload_note;
  EXPECT_NE(first.reload_note.find((dir.path() / "workers" / "broken.key").string() + ":1: "),
            std::string::npos)
      << first.reload_note;
  EXPECT_NE(first.reload_note.find("expected a 40-character Z85 key"), std::string::npos)
      << first.reload_note;
  EXPECT_NE(first.reload_note.find("2 keys (was 3)"), std::string::npos) << first.reload_note;
  const auto kept = allow.decide(as(a));
  EXPECT_TRUE(kept.admitted);
  EXPECT_EQ(kept.name, "a");
  EXPECT_TRUE(allow.decide(as(worker)).admitted);
  EXPECT_EQ(allow.size("workers"), 2u);
  // Said once: the same broken file at the next reload is no news.
  EXPECT_EQ(kept.reload_note, "");
  EXPECT_FALSE(kept.reload_warning);

  // A secret key file dropped in is skipped as a whole and named; its key is not admitted.
  const KeyPair c = generate_key_pair();
  write_key_pair(dir.path() / "secrets", "c", c);
  std::filesystem::copy_file(dir.path() / "secrets" / "c.key_secret",
                             dir.path() / "workers" / "c.key");
  const auto secret = allow.decide(as(c));
  EXPECT_FALSE(secret.admitted);
  EXPECT_TRUE(secret.reload_warning) << secret.reload_note;
  EXPECT_NE(secret.reload_note.find("c.key:"), std::string::npos) << secret.reload_note;
  EXPECT_NE(secret.reload_note.find("secret key"), std::string::npos) << secret.reload_note;
  EXPECT_TRUE(allow.decide(as(a)).admitted);

  // Once the folder is clean again, that is said without a warning.
  std::filesystem::remove(dir.path() / "workers" / "broken.key");
  std::filesystem::remove(dir.path() / "workers" / "c.key");
  const auto clean = allow.decide(as(a));
  EXPECT_TRUE(clean.admitted);
  EXPECT_FALSE(clean.reload_warning) << clean.reload_note;
  EXPECT_NE(clean.reload_note.find("read in full again"), std::string::npos) << clean.reload_note;

  // A list whose path is gone keeps its keys, with a warning.
  std::filesystem::remove_all(dir.path() / "workers");
  const auto gone = allow.decide(as(a));
  EXPECT_TRUE(gone.admitted);
  EXPECT_TRUE(gone.reload_warning) << gone.reload_note;
  EXPECT_NE(gone.reload_note.find("keeping its 2 keys"), std::string::npos) << gone.reload_note;
}

TEST_F(CurveTest, AWrongServerKeyOrAPlainSocketNeverGetsIn) {
  AllowListPolicy allow = policy();
  ZapHandler zap([&](const ZapRequest& r) {
    const auto d = allow.decide(r);
    return ZapVerdict{d.admitted, d.name};
  });
  Router router("tcp://127.0.0.1:0", kDefaultMaxMessageBytes, server_curve("workers"));
  {
    // The right client key, but the server's key is not the one the client expects.
    Dealer wrong(router.endpoint(), kDefaultMaxMessageBytes,
                 client_curve(worker, generate_key_pair().public_key));
    wrong.send({"hello"});
    const HandshakeStatus st = settled(wrong);
    EXPECT_EQ(st.state, Handshake::kFailed) << st.detail;
    EXPECT_NE(st.detail.find("public key"), std::string::npos) << st.detail;
  }
  {
    Dealer plain(router.endpoint());
    plain.send({"hello"});
    const HandshakeStatus st = settled(plain);
    EXPECT_EQ(st.state, Handshake::kFailed) << st.detail;
    EXPECT_NE(st.detail.find("--insecure"), std::string::npos) << st.detail;
  }
  EXPECT_FALSE(router.receive(milliseconds{200}));
}

/// A server socket in another process (tests/common/net_test_peer.cpp): its endpoint and key.
struct PeerProcess {
  std::unique_ptr<test::Process> process;
  std::string endpoint;
  std::string public_key;
};

PeerProcess start_peer(const TempDir& dir, const std::string& mode) {
  PeerProcess peer;
  const std::filesystem::path log = dir.path() / (mode + "-peer.log");
  peer.process = std::make_unique<test::Process>(
      std::vector<std::string>{std::string(RAYFARM_BINARY_DIR) + "/tests/common/net_test_peer",
                               mode},
      log);
  EXPECT_TRUE(test::wait_until([&] { return peer.process->log().find('\n') != std::string::npos; },
                               milliseconds{10000}))
      << peer.process->log();
  std::istringstream line(peer.process->log());
  line >> peer.endpoint >> peer.public_key;
  return peer;
}

// A plain socket against a CURVE server in another process: the server reads the plain greeting
// and hangs up, often before this side has read the greeting that names the server's mechanism.
// A plain socket has no key that could be wrong, so it is told, every time, that the mechanisms
// differ.
TEST_F(CurveTest, APlainSocketIsToldTheServerUsesCurveEveryTime) {
  const PeerProcess peer = start_peer(dir, "curve");
  ASSERT_TRUE(is_key(peer.public_key)) << peer.process->log();
  for (int run = 0; run < 10; ++run) {
    Dealer plain(peer.endpoint);
    plain.send({"hello"});
    const HandshakeStatus st = settled(plain);
    EXPECT_EQ(st.state, Handshake::kFailed) << "run " << run << ": " << st.detail;
    EXPECT_NE(st.detail.find("the peer uses another security mechanism: it has CURVE keys and "
                             "this side runs --insecure"),
              std::string::npos)
        << "run " << run << ": " << st.detail;
    EXPECT_EQ(st.detail.find("public key"), std::string::npos)
        << "run " << run << ": " << st.detail;
  }
  // The same server admits a CURVE socket with its key: it was the mechanism, not the server.
  Dealer keyed(peer.endpoint, kDefaultMaxMessageBytes, client_curve(worker, peer.public_key));
  keyed.send({"hello"});
  EXPECT_EQ(settled(keyed).state, Handshake::kSucceeded) << settled(keyed).detail;
}

// A CURVE socket against a plain server in another process: it hears that the peer may use
// another security mechanism every time (when the server hung up before its greeting was read,
// a wrong server key looks the same to this side, and the message names both).
TEST_F(CurveTest, ACurveSocketIsToldThePlainServerMayUseAnotherMechanismEveryTime) {
  const PeerProcess peer = start_peer(dir, "plain");
  for (int run = 0; run < 10; ++run) {
    Dealer keyed(peer.endpoint, kDefaultMaxMessageBytes, client_curve(worker, server.public_key));
    keyed.send({"hello"});
    const HandshakeStatus st = settled(keyed);
    EXPECT_EQ(st.state, Handshake::kFailed) << "run " << run << ": " << st.detail;
    EXPECT_NE(st.detail.find("the peer uses another security mechanism"), std::string::npos)
        << "run " << run << ": " << st.detail;
    EXPECT_NE(st.detail.find("--insecure"), std::string::npos)
        << "run " << run << ": " << st.detail;
  }
}

TEST_F(CurveTest, OnlyOneZapHandlerCanBeBound) {
  ZapHandler first([](const ZapRequest&) { return ZapVerdict{}; });
  try {
    ZapHandler second([](const ZapRequest&) { return ZapVerdict{true, ""}; });
    FAIL() << "a second ZAP handler was bound";
  } catch (const NetError& e) {
    EXPECT_NE(std::string(e.what()).find("zeromq.zap.01"), std::string::npos) << e.what();
  }
}

TEST(IoThreads, AreSetBeforeTheContextOnlyAndWithinBounds) {
  EXPECT_THROW(set_io_threads(0), NetError);
  EXPECT_THROW(set_io_threads(65), NetError);
  (void)detail::context();  // what the first socket does
  try {
    set_io_threads(2);
    ADD_FAILURE() << "set after the context was made";
  } catch (const NetError& e) {
    EXPECT_NE(std::string(e.what()).find("before the first socket"), std::string::npos);
  }
}

}  // namespace
}  // namespace rayfarm::net

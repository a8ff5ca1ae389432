// CURVE keys: generation, key files (written 0600, read back, the certificate format of czmq and
// pyzmq, bare keys), allow-lists (folders, files of "KEY NAME" lines, secret keys refused, errors
// naming file and line) and the loopback test that guards --insecure.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include "common/net/keys.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::net {
namespace {

using testing::read_file;
using testing::TempDir;

TEST(Keys, CurveIsAvailableAndPairsMatch) {
  ASSERT_TRUE(curve_available()) << "libzmq without libsodium: the farm cannot use CURVE";
  const KeyPair a = generate_key_pair(), b = generate_key_pair();
  EXPECT_TRUE(is_key(a.public_key));
  EXPECT_TRUE(is_key(a.secret_key));
  EXPECT_NE(a.public_key, b.public_key);
  EXPECT_EQ(public_key_of(a.secret_key), a.public_key);
  EXPECT_FALSE(is_key(a.public_key.substr(1)));
  EXPECT_FALSE(is_key(std::string(40, ' ')));
  EXPECT_THROW(public_key_of("not a key"), KeyError);
}

TEST(Keys, WrittenFilesReadBackAndTheSecretOneIsPrivate) {
  TempDir dir;
  const KeyPair keys = generate_key_pair();
  const KeyFiles files = write_key_pair(dir.path() / "keys", "worker-1", keys);
  EXPECT_EQ(files.public_file, dir.path() / "keys" / "worker-1.key");
  EXPECT_EQ(files.secret_file, dir.path() / "keys" / "worker-1.key_secret");
  struct stat st {};
  ASSERT_EQ(::stat(files.secret_file.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_EQ(read_file(files.public_file).find(keys.secret_key), std::string::npos);

  const KeyPair back = read_key_pair(files.secret_file);
  EXPECT_EQ(back.public_key, keys.public_key);
  EXPECT_EQ(back.secret_key, keys.secret_key);
  EXPECT_EQ(read_public_key(files.public_file), keys.public_key);
  EXPECT_EQ(read_public_key(files.secret_file), keys.public_key);  // derived from the secret
  // The public file is not a secret one, and nothing is overwritten.
  EXPECT_THROW(read_key_pair(files.public_file), KeyError);
  EXPECT_THROW(write_key_pair(dir.path() / "keys", "worker-1", generate_key_pair()), KeyError);
  EXPECT_EQ(read_key_pair(files.secret_file).secret_key, keys.secret_key);
  EXPECT_THROW(write_key_pair(dir.path(), "../evil", keys), KeyError);
}

TEST(Keys, BareKeysAndOtherToolsCertificatesAreRead) {
  TempDir dir;
  const KeyPair keys = generate_key_pair();
  const auto bare_secret = dir.write("bare_secret", keys.secret_key + "\n");
  const auto bare_public = dir.write("bare.key", "  " + keys.public_key + "\n");
  EXPECT_EQ(read_key_pair(bare_secret).public_key, keys.public_key);
  EXPECT_EQ(read_public_key(bare_public), keys.public_key);
  // pyzmq's zmq.auth.create_certificates writes this.
  const auto zcert =
      dir.write("client.key_secret",
                "#   ****  Generated on 2024-01-01 by pyzmq  ****\n"
                "#   ZeroMQ CURVE **Secret** Certificate\n\n"
                "metadata\n    email = \"x@example.com\"\ncurve\n"
                "    public-key = \"" +
                    keys.public_key + "\"\n    secret-key = \"" + keys.secret_key + "\"\n");
  EXPECT_EQ(read_key_pair(zcert).secret_key, keys.secret_key);
  // A key given on the command line or in an environment variable instead of a file.
  EXPECT_EQ(key_pair_from(keys.secret_key, "--key").public_key, keys.public_key);
  EXPECT_EQ(public_key_from(keys.public_key, "--master-key"), keys.public_key);
  EXPECT_EQ(public_key_from(bare_public.string(), "--master-key"), keys.public_key);
}

TEST(Keys, MismatchedOrMalformedFilesNameTheFileAndLine) {
  TempDir dir;
  const KeyPair a = generate_key_pair(), b = generate_key_pair();
  const auto mixed =
      dir.write("mixed.key_secret", "curve\n    public-key = \"" + b.public_key +
                                        "\"\n    secret-key = \"" + a.secret_key + "\"\n");
  try {
    read_key_pair(mixed);
    FAIL() << "a public key that is not the secret key's was accepted";
  } catch (const KeyError& e) {
    EXPECT_NE(std::string(e.what()).find("mixed.key_secret:2"), std::string::npos) << e.what();
  }
  const auto garbage = dir.write("garbage.key", "# a comment\nhello world\n");
  try {
    read_public_key(garbage);
    FAIL();
  } catch (const KeyError& e) {
    EXPECT_NE(std::string(e.what()).find("garbage.key:2"), std::string::npos) << e.what();
  }
  try {
    key_pair_from((dir.path() / "missing.key_secret").string(), "--key");
    FAIL();
  } catch (const KeyError& e) {
    EXPECT_NE(std::string(e.what()).find("--key: "), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("missing.key_secret"), std::string::npos) << e.what();
  }
}

TEST(AllowList, AFolderListsItsPublicKeyFilesByName) {
  TempDir dir;
  const KeyPair w1 = generate_key_pair(), w2 = generate_key_pair(), other = generate_key_pair();
  write_key_pair(dir.path() / "workers", "w1", w1);
  write_key_pair(dir.path() / "workers", "w2", w2);  // its .key_secret beside it is skipped
  dir.write("workers/README", "not a key");
  const AllowList list = AllowList::load(dir.path() / "workers");
  EXPECT_EQ(list.size(), 2u);
  ASSERT_NE(list.find(w1.public_key), nullptr);
  EXPECT_EQ(*list.find(w1.public_key), "w1");
  EXPECT_EQ(*list.find(w2.public_key), "w2");
  EXPECT_EQ(list.find(other.public_key), nullptr);
  EXPECT_EQ(list.find(w1.secret_key), nullptr);
}

TEST(AllowList, AFileOfLinesWithCommentsAndNames) {
  TempDir dir;
  const KeyPair a = generate_key_pair(), b = generate_key_pair();
  const auto file = dir.write(
      "clients.txt", "# who may submit\n" + a.public_key + "  alice\n\n" + b.public_key + "\n");
  const AllowList list = AllowList::load(file);
  EXPECT_EQ(list.size(), 2u);
  EXPECT_EQ(*list.find(a.public_key), "alice");
  EXPECT_EQ(*list.find(b.public_key), "clients:4");
  EXPECT_EQ(AllowList::load(dir.write("empty", "# nobody yet\n")).size(), 0u);
}

TEST(AllowList, SecretKeysMissingPathsAndBadLinesAreErrors) {
  TempDir dir;
  const KeyPair a = generate_key_pair();
  write_key_pair(dir.path() / "oops", "a", a);
  // A secret key file renamed to .key in the folder: refused, never silently used.
  std::filesystem::copy_file(dir.path() / "oops" / "a.key_secret", dir.path() / "oops" / "b.key");
  try {
    AllowList::load(dir.path() / "oops");
    FAIL() << "a secret key was accepted in an allow-list";
  } catch (const KeyError& e) {
    EXPECT_NE(std::string(e.what()).find("b.key:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("secret key"), std::string::npos) << e.what();
  }
  EXPECT_THROW(AllowList::load(dir.path() / "nowhere"), KeyError);
  // A truncated key (never starting with '#', which would make the line a comment).
  std::string truncated = a.public_key.substr(3);
  if (truncated[0] == '#') truncated[0] = 'a';
  const auto bad = dir.write("list", a.public_key + "\n" + truncated + " truncated\n");
  try {
    AllowList::load(bad);
    FAIL();
  } catch (const KeyError& e) {
    EXPECT_NE(std::string(e.what()).find("list:2"), std::string::npos) << e.what();
  }
}

TEST(AllowList, ReadingWhatCanBeReadSkipsAndNamesEachBadFileAndLine) {
  TempDir dir;
  const KeyPair w1 = generate_key_pair(), w2 = generate_key_pair(), s = generate_key_pair();
  write_key_pair(dir.path() / "workers", "w1", w1);
  dir.write("workers/broken.key", "nonsense\n");
  write_key_pair(dir.path() / "secret", "s", s);
  std::filesystem::copy_file(dir.path() / "secret" / "s.key_secret",
                             dir.path() / "workers" / "s.key");
  EXPECT_THROW(AllowList::load(dir.path() / "workers"), KeyError);  // strict, as at start
  std::vector<std::string> problems;
  const AllowList list = AllowList::load(dir.path() / "workers", &problems);
  EXPECT_EQ(list.size(), 1u);
  ASSERT_NE(list.find(w1.public_key), nullptr);
  EXPECT_EQ(list.find(s.public_key), nullptr);
  ASSERT_EQ(problems.size(), 2u);
  EXPECT_NE(problems[0].find("broken.key:1: expected a 40-character Z85 key"), std::string::npos)
      << problems[0];
  EXPECT_NE(problems[1].find("s.key:"), std::string::npos) << problems[1];
  EXPECT_NE(problems[1].find("secret key"), std::string::npos) << problems[1];

  // In a file of lines, a bad line is skipped and the others apply.
  const auto file = dir.write("clients.txt", w1.public_key + " one\n" +
                                                 "0123456789 cut\n" +
                                                 w2.public_key + " two\n");
  problems.clear();
  const AllowList lines = AllowList::load(file, &problems);
  EXPECT_EQ(lines.size(), 2u);
  ASSERT_NE(lines.find(w2.public_key), nullptr);
  EXPECT_EQ(*lines.find(w2.public_key), "two");
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("clients.txt:2: "), std::string::npos) << problems[0];
  // A path that is not there is still an error: nothing of it can be read.
  EXPECT_THROW(AllowList::load(dir.path() / "nowhere", &problems), KeyError);
}

TEST(Endpoints, OnlyLoopbackIsLoopback) {
  for (const char* e : {"tcp://127.0.0.1:5555", "tcp://127.1.2.3:1", "tcp://localhost:5556",
                        "tcp://[::1]:5555", "ipc:///tmp/rayfarm.sock", "inproc://x"}) {
    EXPECT_TRUE(is_loopback_endpoint(e)) << e;
  }
  for (const char* e : {"tcp://*:5555", "tcp://0.0.0.0:5555", "tcp://10.0.0.2:5555",
                        "tcp://master:5555", "tcp://128.0.0.1:5555", "tcp://127.0.0.1.evil:1",
                        "tcp://[::]:5555", "tcp://eth0:5555", "udp://127.0.0.1:1", ""}) {
    EXPECT_FALSE(is_loopback_endpoint(e)) << e;
  }
}

}  // namespace
}  // namespace rayfarm::net

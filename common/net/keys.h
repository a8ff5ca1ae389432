#pragma once
// CURVE keys for the farm's sockets: generating key pairs, reading and writing key files, the
// allow-lists of public keys that the master admits, and the loopback test that guards --insecure.
//
// Keys are 32-byte Curve25519 keys written as 40 characters of Z85. Key files use the ZeroMQ
// certificate format (czmq's zcert, pyzmq's zmq.auth), so either side may come from other tools:
//
//   NAME.key          (public; give it to the master's allow-list)    NAME.key_secret  (mode 0600)
//   metadata                                                          metadata
//       name = "NAME"                                                     name = "NAME"
//   curve                                                             curve
//       public-key = "Z85..."                                             public-key = "Z85..."
//                                                                         secret-key = "Z85..."
//
// Wherever a key is read, a file holding just the 40-character key is accepted as well.
#include <cstddef>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rayfarm::net {

/// A key or key file that cannot be used; the message names the file (and line) and the cause.
class KeyError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Characters of a Z85 key.
inline constexpr size_t kKeyChars = 40;

/// A CURVE key pair, both halves in Z85.
struct KeyPair {
  std::string public_key;
  std::string secret_key;
};

/// Whether this libzmq was built with CURVE (libsodium).
bool curve_available();
/// The CURVE check every process makes at start: throws KeyError naming the missing library.
void require_curve();

/// A fresh key pair from libsodium's random source. Throws KeyError when CURVE is unavailable.
KeyPair generate_key_pair();
/// The public key that belongs to a Z85 secret key. Throws KeyError on a malformed key.
std::string public_key_of(const std::string& secret_key);
/// True for 40 characters of Z85 that decode to 32 bytes.
bool is_key(std::string_view text);
/// The 32 bytes of a key as Z85 (for keys that arrive in binary, as in ZAP requests).
std::string z85_of(std::string_view binary_key);
/// A short form of a public key for logs: its first 8 characters.
std::string key_label(const std::string& key);

/// Reads a secret key file (NAME.key_secret, or a file holding the bare secret key) and checks
/// that its public key, when written, belongs to the secret one.
KeyPair read_key_pair(const std::filesystem::path& file);
/// Reads a public key file (NAME.key, or a file holding the bare key).
std::string read_public_key(const std::filesystem::path& file);

/// A key pair given as a secret key file or as the bare Z85 secret key (an environment variable).
KeyPair key_pair_from(const std::string& file_or_key, const std::string& what);
/// A public key given as a file or as the bare Z85 key. `what` names it in errors.
std::string public_key_from(const std::string& file_or_key, const std::string& what);

/// The two files `write_key_pair` wrote.
struct KeyFiles {
  std::filesystem::path public_file;  ///< DIR/NAME.key
  std::filesystem::path secret_file;  ///< DIR/NAME.key_secret, mode 0600
};
/// Writes `keys` as DIR/NAME.key and DIR/NAME.key_secret (created with mode 0600, never readable
/// by others, even for a moment). Refuses to overwrite an existing file. Throws KeyError.
KeyFiles write_key_pair(const std::filesystem::path& dir, const std::string& name,
                        const KeyPair& keys);

/// Public keys that may connect, each with a name for the logs (the file it came from, or the
/// name written beside it).
class AllowList {
 public:
  AllowList() = default;
  /// Reads a file or a folder of public keys. A folder: every `*.key` file in it (secret files
  /// and others are skipped). A file: a public key file, or lines of "KEY [NAME]" with `#`
  /// comments. A secret key, a malformed line or an unreadable file is a KeyError naming the
  /// file and line; an empty list is allowed (it admits no one).
  static AllowList load(const std::filesystem::path& path);
  /// Reads what can be read of a file or folder of public keys: a file that cannot be read or
  /// holds a secret key, and a malformed line, are skipped, each described in `problems` (file,
  /// line and cause) instead of thrown, and every other key is listed. A path that does not exist
  /// or a folder that cannot be listed still throws KeyError: nothing of it could be read.
  static AllowList load(const std::filesystem::path& path, std::vector<std::string>* problems);
  /// A list from (key, name) pairs, for tests.
  static AllowList of(std::map<std::string, std::string> keys);

  /// The name of `key` (Z85) when it is listed, else nullptr.
  const std::string* find(const std::string& key) const;
  size_t size() const { return keys_.size(); }
  bool operator==(const AllowList& other) const { return keys_ == other.keys_; }

 private:
  std::map<std::string, std::string> keys_;  // Z85 key -> name
};

/// True for endpoints only this machine can reach: tcp:// on 127.x.x.x, localhost or [::1],
/// ipc:// and inproc://. "tcp://*:5555" and "tcp://0.0.0.0:5555" are not loopback.
bool is_loopback_endpoint(const std::string& endpoint);

}  // namespace rayfarm::net

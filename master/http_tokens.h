#pragma once
// HTTP bearer tokens: one per client key, so that the dashboard's actions (cancel, pause, resume,
// priority) carry exactly the rights that key has on the client socket. `rayfarm token` asks the
// master over the client socket, where CURVE has already proven the key; the master answers
// "rft1.<the key's name>.<its public key>.<HMAC-SHA256 of both>" (each in hex) under a secret of
// its own, kept in the data dir (http-token.secret, created on first start, readable by the
// master's user only), for the very key the client connected with (the ZAP handler hands it
// over). Tokens need no table: the master checks one by computing its MAC again and asking the
// allow-list whether it still lists that key under that name, so a key taken off the list (or
// listed under another name) loses its token at once, while other keys of the same name keep
// theirs. Deleting the secret file and restarting the master revokes every token.
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

namespace rayfarm::master {

class HttpTokens {
 public:
  /// Reads the secret from `data_dir`/http-token.secret, creating it when absent. Throws
  /// std::runtime_error naming the file when it cannot be read or written.
  explicit HttpTokens(const std::filesystem::path& data_dir);
  /// The name the allow-list lists a public key (Z85) under now; nullopt when it does not.
  using NameOf = std::function<std::optional<std::string>(const std::string& key)>;

  /// A token for the client key `public_key` (Z85) named `key_name` (both "" on a master without
  /// keys).
  std::string issue(const std::string& key_name, const std::string& public_key) const;
  /// The key name a token was issued for, when `name_of` still lists its key under that name;
  /// nullopt when the token is malformed, not this master's, or its key is gone or renamed.
  std::optional<std::string> verify(const std::string& token, const NameOf& name_of) const;

  static constexpr const char* kSecretFile = "http-token.secret";

 private:
  std::string secret_;
  std::string mac(const std::string& key_name, const std::string& public_key) const;
};

}  // namespace rayfarm::master

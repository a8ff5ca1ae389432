#pragma once
// HTTP bearer tokens: one per client key, so that the dashboard's actions (cancel, pause, resume,
// priority) carry exactly the rights that key has on the client socket. `rayfarm token` asks the
// master over the client socket, where CURVE has already proven the key; the master answers
// "rft1.<hex of the key's name>.<HMAC-SHA256 of the name>" under a secret of its own, kept in the
// data dir (http-token.secret, created on first start, readable by the master's user only).
// Tokens need no table: the master checks one by computing its MAC again. Deleting the secret
// file and restarting the master revokes every token; a key taken off the allow-list loses its
// token's rights at once (HttpServer asks the allow-list on every request).
#include <filesystem>
#include <optional>
#include <string>

namespace rayfarm::master {

class HttpTokens {
 public:
  /// Reads the secret from `data_dir`/http-token.secret, creating it when absent. Throws
  /// std::runtime_error naming the file when it cannot be read or written.
  explicit HttpTokens(const std::filesystem::path& data_dir);
  /// A token for the client key named `key_name` ("" on a master without keys).
  std::string issue(const std::string& key_name) const;
  /// The key name a token was issued for; nullopt when it is malformed or not this master's.
  std::optional<std::string> verify(const std::string& token) const;

  static constexpr const char* kSecretFile = "http-token.secret";

 private:
  std::string secret_;
  std::string mac(const std::string& key_name) const;
};

}  // namespace rayfarm::master

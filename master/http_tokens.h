#pragma once
// HTTP bearer tokens: one per client key, so that the dashboard's actions (cancel, pause, resume,
// priority) carry exactly the rights that key has on the client socket. `rayfarm token` asks the
// master over the client socket, where CURVE has already proven the key; the master answers
// "rft1.<hex of the key's name>.<HMAC-SHA256 of the name and the public key>" under a secret of
// its own, kept in the data dir (http-token.secret, created on first start, readable by the
// master's user only). Tokens need no table: the master checks one by computing its MAC again
// with the key the allow-list names now, so a key taken off the list, or replaced by another
// under the same name, loses its token at once. Deleting the secret file and restarting the
// master revokes every token.
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
  /// The public key the allow-list names a key name by now; nullopt when none.
  using KeyOf = std::function<std::optional<std::string>(const std::string& name)>;

  /// A token for the client key named `key_name` whose public key is `public_key` (both "" on a
  /// master without keys).
  std::string issue(const std::string& key_name, const std::string& public_key) const;
  /// The key name a token was issued for, when `key_of` still names the same public key by it;
  /// nullopt when the token is malformed, not this master's, or its key is gone or replaced.
  std::optional<std::string> verify(const std::string& token, const KeyOf& key_of) const;

  static constexpr const char* kSecretFile = "http-token.secret";

 private:
  std::string secret_;
  std::string mac(const std::string& key_name, const std::string& public_key) const;
};

}  // namespace rayfarm::master

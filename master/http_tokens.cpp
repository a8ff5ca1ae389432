#include "master/http_tokens.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>

namespace rayfarm::master {
namespace {

constexpr size_t kSecretBytes = 32;
constexpr const char* kPrefix = "rft1.";
/// Key names are short; a longer token is not one of ours, whatever it holds.
constexpr size_t kMaxNameBytes = 256;

std::string hex(const std::string& bytes) {
  static const char* digits = "0123456789abcdef";
  std::string out;
  out.reserve(bytes.size() * 2);
  for (unsigned char c : bytes) {
    out += digits[c >> 4];
    out += digits[c & 15];
  }
  return out;
}

std::optional<std::string> unhex(const std::string& text) {
  if (text.size() % 2 != 0) return std::nullopt;
  auto digit = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    return -1;
  };
  std::string out;
  for (size_t i = 0; i < text.size(); i += 2) {
    const int hi = digit(text[i]), lo = digit(text[i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    out += static_cast<char>(hi * 16 + lo);
  }
  return out;
}

std::string read_or_create(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (in) {
    std::string secret((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (secret.size() != kSecretBytes) {
      throw std::runtime_error(path.string() + ": not an HTTP token secret (" +
                               std::to_string(secret.size()) + " bytes, expected " +
                               std::to_string(kSecretBytes) +
                               "); delete it to make a new one (every token changes)");
    }
    return secret;
  }
  std::string secret(kSecretBytes, '\0');
  if (RAND_bytes(reinterpret_cast<unsigned char*>(secret.data()), kSecretBytes) != 1) {
    throw std::runtime_error("cannot draw random bytes for the HTTP token secret");
  }
  // Written under a temporary name and renamed, readable by this user only.
  const std::filesystem::path tmp = path.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) {
    throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(errno));
  }
  const bool ok = ::write(fd, secret.data(), secret.size()) == static_cast<ssize_t>(secret.size()) &&
                  ::fsync(fd) == 0;
  const int err = errno;
  ::close(fd);
  if (!ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::filesystem::remove(tmp);
    throw std::runtime_error("cannot write " + path.string() + ": " + std::strerror(ok ? errno : err));
  }
  return secret;
}

}  // namespace

HttpTokens::HttpTokens(const std::filesystem::path& data_dir)
    : secret_(read_or_create(data_dir / kSecretFile)) {}

std::string HttpTokens::mac(const std::string& key_name, const std::string& public_key) const {
  const std::string message = "rayfarm http token\n" + key_name + "\n" + public_key;
  unsigned char out[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  if (!HMAC(EVP_sha256(), secret_.data(), static_cast<int>(secret_.size()),
            reinterpret_cast<const unsigned char*>(message.data()), message.size(), out, &len)) {
    throw std::runtime_error("HMAC-SHA256 failed");
  }
  return std::string(reinterpret_cast<const char*>(out), len);
}

std::string HttpTokens::issue(const std::string& key_name, const std::string& public_key) const {
  return kPrefix + hex(key_name) + "." + hex(public_key) + "." + hex(mac(key_name, public_key));
}

std::optional<std::string> HttpTokens::verify(const std::string& token, const NameOf& name_of) const {
  const std::string prefix = kPrefix;
  if (token.size() > prefix.size() + 2 * kMaxNameBytes + 1 + 2 * 64 + 1 + 64 ||
      token.compare(0, prefix.size(), prefix) != 0) {
    return std::nullopt;
  }
  // NAME.KEY.MAC, each in hex (Z85, the key's own text, has '.' in its alphabet).
  const std::string rest = token.substr(prefix.size());
  const size_t dot1 = rest.find('.');
  const size_t dot2 = dot1 == std::string::npos ? dot1 : rest.find('.', dot1 + 1);
  if (dot2 == std::string::npos) return std::nullopt;
  const auto name = unhex(rest.substr(0, dot1));
  const auto key = unhex(rest.substr(dot1 + 1, dot2 - dot1 - 1));
  const auto given = unhex(rest.substr(dot2 + 1));
  if (!name || !key || !given) return std::nullopt;
  const std::optional<std::string> listed_as = name_of(*key);
  if (!listed_as || *listed_as != *name) return std::nullopt;
  const std::string expected = mac(*name, *key);
  if (given->size() != expected.size() ||
      CRYPTO_memcmp(given->data(), expected.data(), expected.size()) != 0) {
    return std::nullopt;
  }
  return name;
}

}  // namespace rayfarm::master

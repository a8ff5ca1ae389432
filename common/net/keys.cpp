#include "common/net/keys.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>
#include <system_error>
#include <vector>

#include <zmq.h>

#include "common/util/read_file.h"

namespace rayfarm::net {
namespace fs = std::filesystem;

namespace {

/// Key files are small; anything larger is not one.
constexpr std::uintmax_t kMaxKeyFileBytes = 1 << 20;

std::string trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r\n");
  return std::string(s.substr(first, last - first + 1));
}

std::string read_small_file(const fs::path& file) {
  try {
    return read_whole_file(file, kMaxKeyFileBytes);
  } catch (const FileReadError& e) {
    if (e.kind() == FileReadError::Kind::kTooLarge) {
      throw KeyError(file.string() + ": " + std::to_string(e.size()) +
                     " bytes is too large for a key file");
    }
    throw KeyError(file.string() + ": cannot read: " + e.what());
  }
}

/// What one key file or list holds.
struct Parsed {
  struct Entry {
    std::string key;
    std::string name;
    int line = 0;
  };
  std::vector<Entry> public_keys;
  std::optional<Parsed::Entry> secret_key;
  std::string name;  // metadata name = "..."
};

/// The value of `field = "VALUE"` (quotes optional), or nullopt when `line` is not that field.
std::optional<std::string> field_value(const std::string& line, std::string_view field) {
  if (line.rfind(field, 0) != 0) return std::nullopt;
  std::string rest = trim(std::string_view(line).substr(field.size()));
  if (rest.empty() || rest[0] != '=') return std::nullopt;
  rest = trim(std::string_view(rest).substr(1));
  if (rest.size() >= 2 && rest.front() == '"' && rest.back() == '"') {
    rest = rest.substr(1, rest.size() - 2);
  }
  return rest;
}

std::string where(const fs::path& file, int line) {
  return file.string() + ":" + std::to_string(line);
}

/// Parses a key file: the certificate format, a bare key, or lines of "KEY [NAME]". A bad line
/// throws KeyError, or, when `problems` is given, is described there and skipped.
Parsed parse_key_text(const std::string& text, const fs::path& file,
                      std::vector<std::string>* problems = nullptr) {
  Parsed parsed;
  std::istringstream in(text);
  std::string raw;
  int line_no = 0;
  const auto bad_line = [&](const std::string& why) {
    if (!problems) throw KeyError(where(file, line_no) + ": " + why);
    problems->push_back(where(file, line_no) + ": " + why);
  };
  while (std::getline(in, raw)) {
    ++line_no;
    const std::string line = trim(raw);
    if (line.empty()) continue;
    if (auto v = field_value(line, "public-key")) {
      if (!is_key(*v)) {
        bad_line("public-key is not a 40-character Z85 key");
        continue;
      }
      parsed.public_keys.push_back({*v, "", line_no});
      continue;
    }
    if (auto v = field_value(line, "secret-key")) {
      if (!is_key(*v)) {
        bad_line("secret-key is not a 40-character Z85 key");
        continue;
      }
      parsed.secret_key = Parsed::Entry{*v, "", line_no};
      continue;
    }
    if (auto v = field_value(line, "name")) {
      if (parsed.name.empty()) parsed.name = *v;
      continue;
    }
    // "KEY [NAME]": the first word is a key. (Z85 may begin with '#', so this comes first.)
    const size_t space = line.find_first_of(" \t");
    const std::string first = line.substr(0, space);
    if (is_key(first)) {
      parsed.public_keys.push_back(
          {first, space == std::string::npos ? "" : trim(line.substr(space)), line_no});
      continue;
    }
    if (line[0] == '#' || line == "metadata" || line == "curve") continue;
    if (line.find('=') != std::string::npos && raw.find_first_of(" \t") == 0) {
      continue;  // other metadata of a certificate, e.g. `    email = "..."`
    }
    bad_line("expected a 40-character Z85 key, \"public-key = ...\" or a # comment");
  }
  return parsed;
}

std::string timestamp() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S UTC", &tm);
  return buf;
}

/// Creates `file` exclusively with `mode` and writes `text`; never overwrites.
void write_new_file(const fs::path& file, const std::string& text, mode_t mode) {
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, mode);
  if (fd < 0) {
    const int err = errno;
    if (err == EEXIST) {
      throw KeyError(file.string() + " already exists; remove it first or choose another name");
    }
    throw KeyError("cannot create " + file.string() + ": " + std::strerror(err));
  }
  ::fchmod(fd, mode);  // whatever the umask
  size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = errno;
      ::close(fd);
      throw KeyError("cannot write " + file.string() + ": " + std::strerror(err));
    }
    written += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    throw KeyError("cannot write " + file.string() + ": " + std::strerror(errno));
  }
}

bool looks_like_file(const std::string& value) {
  std::error_code ec;
  return fs::exists(value, ec) || !is_key(value);
}

}  // namespace

bool curve_available() { return zmq_has("curve") != 0; }

void require_curve() {
  if (!curve_available()) {
    throw KeyError(
        "this libzmq has no CURVE support (it needs libsodium): install Debian's libzmq5, or run "
        "with --insecure on loopback");
  }
}

KeyPair generate_key_pair() {
  require_curve();
  char pub[kKeyChars + 1] = {}, sec[kKeyChars + 1] = {};
  if (zmq_curve_keypair(pub, sec) != 0) {
    throw KeyError(std::string("cannot generate a key pair: ") + zmq_strerror(zmq_errno()));
  }
  return {pub, sec};
}

std::string public_key_of(const std::string& secret_key) {
  require_curve();
  if (!is_key(secret_key)) throw KeyError("not a 40-character Z85 secret key");
  char pub[kKeyChars + 1] = {};
  if (zmq_curve_public(pub, secret_key.c_str()) != 0) {
    throw KeyError(std::string("cannot derive the public key: ") + zmq_strerror(zmq_errno()));
  }
  return pub;
}

bool is_key(std::string_view text) {
  if (text.size() != kKeyChars) return false;
  static constexpr std::string_view kZ85 =
      "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.-:+=^!/*?&<>()[]{}@%$#";
  if (text.find_first_not_of(kZ85) != std::string_view::npos) return false;
  uint8_t bytes[32];
  const std::string copy(text);
  return zmq_z85_decode(bytes, copy.c_str()) != nullptr;
}

std::string z85_of(std::string_view binary_key) {
  if (binary_key.size() != 32) return "<a key of " + std::to_string(binary_key.size()) + " bytes>";
  char out[kKeyChars + 1] = {};
  zmq_z85_encode(out, reinterpret_cast<const uint8_t*>(binary_key.data()), binary_key.size());
  return out;
}

std::string key_label(const std::string& key) { return key.substr(0, 8); }

KeyPair read_key_pair(const fs::path& file) {
  const std::string text = read_small_file(file);
  KeyPair keys;
  if (is_key(trim(text))) {
    keys.secret_key = trim(text);  // a file holding the bare secret key
    keys.public_key = public_key_of(keys.secret_key);
    return keys;
  }
  const Parsed p = parse_key_text(text, file);
  if (!p.secret_key) {
    throw KeyError(file.string() +
                   ": no secret-key in it; give the secret key file (NAME.key_secret), not the "
                   "public one");
  }
  keys.secret_key = p.secret_key->key;
  keys.public_key = public_key_of(keys.secret_key);
  for (const auto& e : p.public_keys) {
    if (e.key != keys.public_key) {
      throw KeyError(where(file, e.line) +
                     ": public-key does not belong to the secret-key in the same file");
    }
  }
  return keys;
}

std::string read_public_key(const fs::path& file) {
  const Parsed p = parse_key_text(read_small_file(file), file);
  if (p.public_keys.size() == 1) return p.public_keys[0].key;
  if (p.public_keys.empty()) {
    if (p.secret_key) return public_key_of(p.secret_key->key);
    throw KeyError(file.string() + ": no public key in it");
  }
  throw KeyError(file.string() + ": " + std::to_string(p.public_keys.size()) +
                 " public keys in it; expected one");
}

KeyPair key_pair_from(const std::string& file_or_key, const std::string& what) {
  try {
    if (looks_like_file(file_or_key)) return read_key_pair(file_or_key);
    return {public_key_of(file_or_key), file_or_key};
  } catch (const KeyError& e) {
    throw KeyError(what + ": " + e.what());
  }
}

std::string public_key_from(const std::string& file_or_key, const std::string& what) {
  try {
    if (looks_like_file(file_or_key)) return read_public_key(file_or_key);
    return file_or_key;
  } catch (const KeyError& e) {
    throw KeyError(what + ": " + e.what());
  }
}

KeyFiles write_key_pair(const fs::path& dir, const std::string& name, const KeyPair& keys) {
  if (name.empty() || name.find('/') != std::string::npos || name == "." || name == "..") {
    throw KeyError("bad key name '" + name + "': use letters, digits, '-', '_' or '.'");
  }
  for (char c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') {
      throw KeyError("bad key name '" + name + "': use letters, digits, '-', '_' or '.'");
    }
  }
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw KeyError("cannot create " + dir.string() + ": " + ec.message());
  KeyFiles files{dir / (name + ".key"), dir / (name + ".key_secret")};
  const std::string header = "#   ****  Generated on " + timestamp() + " by rayfarm keygen  ****\n";
  const std::string meta = "\nmetadata\n    name = \"" + name + "\"\ncurve\n    public-key = \"" +
                           keys.public_key + "\"\n";
  const std::string secret_text =
      header +
      "#   ZeroMQ CURVE **Secret** Certificate\n"
      "#   DO NOT PROVIDE THIS FILE TO OTHER USERS nor change its permissions.\n" +
      meta + "    secret-key = \"" + keys.secret_key + "\"\n";
  const std::string public_text =
      header +
      "#   ZeroMQ CURVE Public Certificate\n"
      "#   Give this file to whoever must recognise this key: a worker's or a client's to the\n"
      "#   master's allow-list (--worker-keys, --client-keys); the master's to its workers and\n"
      "#   clients (--master-key).\n" +
      meta;
  if (fs::exists(files.public_file, ec)) {
    throw KeyError(files.public_file.string() +
                   " already exists; remove it first or choose another name");
  }
  write_new_file(files.secret_file, secret_text, 0600);
  try {
    write_new_file(files.public_file, public_text, 0644);
  } catch (...) {
    fs::remove(files.secret_file, ec);
    throw;
  }
  return files;
}

AllowList AllowList::load(const fs::path& path) { return load(path, nullptr); }

AllowList AllowList::load(const fs::path& path, std::vector<std::string>* problems) {
  AllowList list;
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (ec || !fs::exists(status)) {
    throw KeyError(path.string() + ": no such file or folder of public keys");
  }
  std::vector<fs::path> files;
  if (fs::is_directory(status)) {
    for (const auto& entry : fs::directory_iterator(path, ec)) {
      const fs::path& f = entry.path();
      if (f.extension() == ".key" && entry.is_regular_file(ec)) files.push_back(f);
    }
    if (ec) throw KeyError("cannot list " + path.string() + ": " + ec.message());
    std::sort(files.begin(), files.end());
  } else {
    files.push_back(path);
  }
  for (const auto& file : files) {
    std::string text;
    try {
      text = read_small_file(file);
    } catch (const KeyError& e) {
      if (!problems) throw;
      problems->push_back(e.what());
      continue;
    }
    const Parsed p = parse_key_text(text, file, problems);
    if (p.secret_key) {
      const std::string why = where(file, p.secret_key->line) +
                              ": a secret key has no place in an allow-list; give the public key "
                              "file (NAME.key) and keep NAME.key_secret on its machine";
      if (!problems) throw KeyError(why);
      problems->push_back(why + " (none of this file's keys apply)");
      continue;
    }
    for (const auto& e : p.public_keys) {
      // The name is the operator's: a name on the key's line of a list file, else the file's
      // name. A name written inside a key file is its holder's choice, and names are what
      // ownership and --admin-clients go by, so it is not used.
      std::string name = !e.name.empty() ? e.name : file.stem().string();
      if (p.public_keys.size() > 1 && e.name.empty())
        name.append(":").append(std::to_string(e.line));
      list.keys_.emplace(e.key, std::move(name));
    }
  }
  return list;
}

AllowList AllowList::of(std::map<std::string, std::string> keys) {
  AllowList list;
  list.keys_ = std::move(keys);
  return list;
}

const std::string* AllowList::find(const std::string& key) const {
  auto it = keys_.find(key);
  return it == keys_.end() ? nullptr : &it->second;
}

bool is_loopback_endpoint(const std::string& endpoint) {
  if (endpoint.rfind("ipc://", 0) == 0 || endpoint.rfind("inproc://", 0) == 0) return true;
  if (endpoint.rfind("tcp://", 0) != 0) return false;
  std::string host = endpoint.substr(6);
  // A connect endpoint may name a source: "tcp://SRC;HOST:PORT"; the host is what matters.
  if (const size_t semi = host.find(';'); semi != std::string::npos) host = host.substr(semi + 1);
  if (!host.empty() && host[0] == '[') {
    const size_t close = host.find(']');
    return close != std::string::npos && host.substr(1, close - 1) == "::1";
  }
  host = host.substr(0, host.rfind(':'));
  if (host == "localhost") return true;
  // 127.0.0.0/8, written as four numbers.
  unsigned a = 0, b = 0, c = 0, d = 0;
  char tail = 0;
  if (std::sscanf(host.c_str(), "%u.%u.%u.%u%c", &a, &b, &c, &d, &tail) == 4) {
    return a == 127 && b < 256 && c < 256 && d < 256;
  }
  return false;
}

}  // namespace rayfarm::net

#pragma once
// SHA-256 (OpenSSL libcrypto): bundles are named by it, checkpoints checked with it.
#include <array>
#include <string>
#include <string_view>

namespace rayfarm {

/// A SHA-256 digest, 32 bytes.
using Sha256Digest = std::array<unsigned char, 32>;

/// SHA-256 of `bytes`. Throws std::runtime_error when OpenSSL fails.
Sha256Digest sha256(std::string_view bytes);

/// SHA-256 of `bytes`, 64 lowercase hex digits.
std::string sha256_hex(std::string_view bytes);

}  // namespace rayfarm

#pragma once
// SHA-256 digests for provenance (unit records, harness shards): OpenSSL's libcrypto does the hashing.
#include <string>
#include <string_view>

namespace topocal::util {

// Lower-case hex SHA-256 of the bytes.
std::string Sha256Hex(std::string_view bytes);
// Lower-case hex SHA-256 of a file's bytes. Throws InputError naming the path if it cannot be read.
std::string Sha256HexOfFile(const std::string& path);

}  // namespace topocal::util

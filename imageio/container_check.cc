#include "imageio/container_check.h"

#include <fmt/format.h>
#include <libdeflate.h>

#include <cstdint>

#include "util/io.h"

namespace topocal::imageio {
namespace {


unsigned char Byte(std::string_view b, std::size_t at) { return static_cast<unsigned char>(b[at]); }

std::string ChunkType(std::string_view type) {
  for (const char c : type) {
    if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'))) return "(not a chunk type)";
  }
  return std::string(type);
}

void CheckPng(std::string_view b, const std::string& name) {
  std::size_t at = 8;
  while (true) {
    if (at + 12 > b.size()) {
      throw util::InputError(fmt::format("{}: cannot be read as an image (truncated PNG: the file ends at byte {} without an IEND chunk)", name,
                                         b.size()));
    }
    const std::uint64_t length = BigEndian32(b, at);
    const std::string type = ChunkType(b.substr(at + 4, 4));
    if (length > 0x7fffffffu || at + 12 + length > b.size()) {
      throw util::InputError(fmt::format("{}: cannot be read as an image (truncated PNG: chunk {} at byte {} runs past "
                                         "the end of the file, {} bytes)",
                                         name, type, at, b.size()));
    }
    // libdeflate's CRC-32 (the PNG one), several times zlib's speed on a 17 MB image's chunks.
    const std::uint32_t crc = libdeflate_crc32(0, b.data() + at + 4, static_cast<std::size_t>(4 + length));
    if (crc != BigEndian32(b, at + 8 + length)) {
      throw util::InputError(fmt::format("{}: cannot be read as an image (damaged PNG: chunk {} at byte {} fails its CRC)", name, type, at));
    }
    if (type == "IEND") return;
    at += 12 + length;
  }
}

// After SOS: the entropy-coded data run until a marker other than a stuffed 0xFF00, a fill byte or RSTn.
std::size_t SkipScan(std::string_view b, std::size_t at) {
  while (at + 1 < b.size()) {
    if (Byte(b, at) != 0xFF) {
      ++at;
      continue;
    }
    const unsigned char next = Byte(b, at + 1);
    if (next == 0x00 || next == 0xFF || (next >= 0xD0 && next <= 0xD7)) {
      at += next == 0xFF ? 1 : 2;
      continue;
    }
    return at;  // a marker
  }
  return b.size();
}

void CheckJpeg(std::string_view b, const std::string& name) {
  const auto truncated = [&](std::size_t at) {
    return util::InputError(fmt::format("{}: cannot be read as an image (truncated JPEG: the file ends at byte {} "
                                        "before its end-of-image marker; the segment at byte {} runs past it)",
                                        name, b.size(), at));
  };
  std::size_t at = 2;
  while (true) {
    if (at + 2 > b.size()) throw truncated(at);
    if (Byte(b, at) != 0xFF) {
      throw util::InputError(fmt::format("{}: cannot be read as an image (damaged JPEG: no marker at byte {})", name, at));
    }
    const unsigned char code = Byte(b, at + 1);
    if (code == 0xFF) {  // fill byte
      ++at;
      continue;
    }
    if (code == 0xD9) return;  // EOI
    if (code == 0x01 || (code >= 0xD0 && code <= 0xD8)) {  // markers without a length
      at += 2;
      continue;
    }
    if (at + 4 > b.size()) throw truncated(at);
    const std::size_t length = (static_cast<std::size_t>(Byte(b, at + 2)) << 8) | Byte(b, at + 3);
    if (length < 2) throw util::InputError(fmt::format("{}: cannot be read as an image (damaged JPEG: segment length {} at byte {})", name, length, at));
    if (at + 2 + length > b.size()) throw truncated(at);
    at += 2 + length;
    if (code == 0xDA) at = SkipScan(b, at);  // SOS: its entropy-coded data follow the header
  }
}

}  // namespace

std::uint32_t BigEndian32(std::string_view b, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return v;
}

void CheckContainer(std::string_view bytes, const std::string& name) {
  static constexpr std::string_view kPngSignature("\x89PNG\r\n\x1a\n", 8);
  if (bytes.size() >= 8 && bytes.substr(0, 8) == kPngSignature) {
    CheckPng(bytes, name);
  } else if (bytes.size() >= 3 && Byte(bytes, 0) == 0xFF && Byte(bytes, 1) == 0xD8 && Byte(bytes, 2) == 0xFF) {
    CheckJpeg(bytes, name);
  }
}

}  // namespace topocal::imageio

#pragma once

// Recognising the same file elsewhere (renamed, moved, copied) without reading all of it, and the
// hash it is built on.

#include "core/util/status.h"

#include <cstddef>
#include <cstdint>
#include <string>

namespace saker {

// The 64-bit FNV-1a offset basis: the `hash` to start a new hash with.
inline constexpr uint64_t kFnv1aOffset = 0xcbf29ce484222325ull;

// 64-bit FNV-1a of `size` bytes, continuing from `hash` (so a hash can be fed in pieces). Not
// cryptographic: it tells files and settings apart, it does not resist forgery.
uint64_t Fnv1a(const void* data, size_t size, uint64_t hash = kFnv1aOffset);

// A fingerprint that recognises the same video file elsewhere without reading all of a
// multi-gigabyte file: "v1:<size in bytes>:<16 hex digits>", the digits a 64-bit FNV-1a hash of
// the size and of the first, middle and last MiB of the file (see docs/mission-file.md). NotFound
// when the file is missing, IoError when it cannot be read; the message names the path.
StatusOr<std::string> FingerprintFile(const std::string& path);

}  // namespace saker

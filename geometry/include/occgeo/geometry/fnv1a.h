#pragma once

#include <cstdint>
#include <span>
#include <string_view>

namespace occgeo::geometry {

// The 64-bit FNV-1a offset basis: the hash of no bytes, and where a chain of fnv1a calls starts.
inline constexpr std::uint64_t kFnv1aBasis = 14695981039346656037ULL;

// 64-bit FNV-1a of bytes, continuing from `hash` (so fnv1a(b, fnv1a(a)) hashes a then b). Stable across machines
// and runs: for checksums in files and for noticing changed data, not for anything an attacker chooses.
constexpr std::uint64_t fnv1a(std::string_view bytes, std::uint64_t hash = kFnv1aBasis) {
  for (const char c : bytes) hash = (hash ^ static_cast<unsigned char>(c)) * 1099511628211ULL;
  return hash;
}
inline std::uint64_t fnv1a(std::span<const std::uint8_t> bytes, std::uint64_t hash = kFnv1aBasis) {
  for (const std::uint8_t b : bytes) hash = (hash ^ b) * 1099511628211ULL;
  return hash;
}

}  // namespace occgeo::geometry

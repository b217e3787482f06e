// SHA-256 (FIPS 180-4), for the checksums of run manifests: `sha256sum` gives the same digests.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

namespace granflow::io {

// Blocks go through the CPU's SHA extensions (x86-64 SHA-NI) where it has them, about ten times
// the portable code's 160 MB/s here: AtomicFile hashes every byte a run writes.
class Sha256 {
 public:
  Sha256();
  void update(std::string_view bytes);
  std::string hex();  // finishes the digest; call once

 private:
  void blocks(const unsigned char* p, std::size_t count);
  void block(const unsigned char* p);
  std::array<std::uint32_t, 8> h_;
  unsigned char buf_[64];
  std::size_t fill_ = 0;
  std::uint64_t length_ = 0;
};

std::string sha256_hex(std::string_view bytes);

// Whether the SHA extensions are used (the CPU has them, and the last call below allowed them).
bool sha256_cpu_extensions();
// Allows (default) or forbids them, process-wide; tests check both paths give the same digests.
void sha256_allow_cpu_extensions(bool allow);

}  // namespace granflow::io

// SHA-256 (FIPS 180-4), for the checksums of run manifests: `sha256sum` gives the same digests.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

namespace granflow::io {

class Sha256 {
 public:
  Sha256();
  void update(std::string_view bytes);
  std::string hex();  // finishes the digest; call once

 private:
  void block(const unsigned char* p);
  std::array<std::uint32_t, 8> h_;
  unsigned char buf_[64];
  std::size_t fill_ = 0;
  std::uint64_t length_ = 0;
};

std::string sha256_hex(std::string_view bytes);

}  // namespace granflow::io

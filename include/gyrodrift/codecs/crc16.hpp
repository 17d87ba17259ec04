// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, xorout 0x0000), the CRC of
// the serial IMU frame. Check value: crc16_ccitt_false("123456789") == 0x29B1.
// Table-driven (512 bytes of const table, built at compile time), no allocation.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>

namespace gyrodrift {

namespace detail {
constexpr std::array<std::uint16_t, 256> make_crc16_ccitt_table() noexcept {
  std::array<std::uint16_t, 256> table{};
  for (std::size_t byte = 0; byte < 256; ++byte) {
    auto crc = static_cast<std::uint32_t>(byte << 8);  // unsigned arithmetic throughout
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x8000U) != 0U ? ((crc << 1U) ^ 0x1021U) : (crc << 1U);
    }
    table[byte] = static_cast<std::uint16_t>(crc & 0xFFFFU);
  }
  return table;
}
inline constexpr std::array<std::uint16_t, 256> kCrc16CcittTable = make_crc16_ccitt_table();
}  // namespace detail

inline constexpr std::uint16_t kCrc16CcittInit = 0xFFFFU;

// Continues a CRC over n bytes (pass the previous return value as `crc` to chain blocks).
inline std::uint16_t crc16_ccitt_false(const std::uint8_t* data, std::size_t n,
                                       std::uint16_t crc = kCrc16CcittInit) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<std::uint32_t>(crc);
    const auto index = static_cast<std::size_t>(((c >> 8U) ^ data[i]) & 0xFFU);
    crc = static_cast<std::uint16_t>(((c << 8U) ^ detail::kCrc16CcittTable[index]) & 0xFFFFU);
  }
  return crc;
}

}  // namespace gyrodrift

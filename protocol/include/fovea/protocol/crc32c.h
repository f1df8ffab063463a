// SPDX-License-Identifier: Apache-2.0
#pragma once
// CRC-32C (Castagnoli, reflected polynomial 0x82F63B78), as used by iSCSI, ext4 and SCTP.
#include <cstddef>
#include <cstdint>
#include <span>

namespace fovea::protocol {

std::uint32_t crc32c(std::span<const std::uint8_t> data, std::uint32_t crc = 0);

}  // namespace fovea::protocol

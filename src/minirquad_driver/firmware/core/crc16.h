// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, not reflected, no final xor.
// Check value: 0x29B1 for "123456789" (Python: binascii.crc_hqx(data, 0xFFFF)).
#ifndef MRQ_CRC16_H
#define MRQ_CRC16_H

#include <stddef.h>
#include <stdint.h>

namespace mrq {

uint16_t crc16_ccitt_false(const uint8_t* data, size_t n, uint16_t crc = 0xFFFF);

}  // namespace mrq

#endif

// Little-endian loads and stores by byte shifts: no alignment assumptions (a Cortex-M0+
// faults on an unaligned word access) and no dependence on the host's byte order.
#ifndef MRQ_WIRE_H
#define MRQ_WIRE_H

#include <stddef.h>
#include <stdint.h>

namespace mrq {

inline uint16_t get_u16(const uint8_t* p) { return uint16_t(p[0] | (uint16_t(p[1]) << 8)); }
inline int16_t get_i16(const uint8_t* p) { return int16_t(get_u16(p)); }
inline uint32_t get_u32(const uint8_t* p) {
  return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) |
         (uint32_t(p[3]) << 24);
}
inline int32_t get_i32(const uint8_t* p) { return int32_t(get_u32(p)); }

inline void put_u16(uint8_t* p, uint16_t v) {
  p[0] = uint8_t(v);
  p[1] = uint8_t(v >> 8);
}
inline void put_u32(uint8_t* p, uint32_t v) {
  p[0] = uint8_t(v);
  p[1] = uint8_t(v >> 8);
  p[2] = uint8_t(v >> 16);
  p[3] = uint8_t(v >> 24);
}

}  // namespace mrq

#endif

// Consistent Overhead Byte Stuffing (Cheshire and Baker, 1999), as protocol/cobs.py.
#ifndef MRQ_COBS_H
#define MRQ_COBS_H

#include <stddef.h>
#include <stdint.h>

namespace mrq {

// Encode n bytes into out (no 0x00 in the result). Returns the encoded length, or 0 if
// cap is too small (an encoding is never empty). Canonical: input that ends exactly on a
// full 254-byte block gets no trailing empty block.
size_t cobs_encode(const uint8_t* in, size_t n, uint8_t* out, size_t cap);

// Decode n bytes (a segment between delimiters) into out; out may equal in (the output
// never overtakes the input). Returns false on an empty segment, a zero byte or a code
// that runs past the end; *out_len is then unspecified. cap must be at least n.
bool cobs_decode(const uint8_t* in, size_t n, uint8_t* out, size_t cap, size_t* out_len);

}  // namespace mrq

#endif
